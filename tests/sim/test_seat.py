"""Simulated users move in their seat, and the simulated Mini turns its joints toward
what an aim command names, at their speeds, reporting where they are."""

from __future__ import annotations

import itertools
from datetime import UTC, datetime, timedelta

import pytest

from dms.kernel.body import JOINTS
from dms.kernel.messages import RobotCommand
from sim.robot import SimRobot
from sim.seat import HOME, Seat, SeatSettings

T0 = datetime(2026, 11, 24, 10, 0, tzinfo=UTC)


def test_a_seated_face_stays_put_then_moves_within_reach_and_settles() -> None:
    seat = Seat(T0, "ann:seat")
    settings = SeatSettings()
    assert seat.face(T0) == HOME
    faces = [seat.face(T0 + timedelta(seconds=s)) for s in range(0, 1800, 1)]
    moves = sum(1 for a, b in itertools.pairwise(faces) if a != b)
    assert moves > 10  # half an hour: she leaned and shifted more than a few times
    assert len(set(faces)) > 10
    for x, y, z in faces[60 * 3 :]:
        assert settings.x[0] <= x <= settings.x[1]
        assert settings.y[0] <= y <= settings.y[1]
        assert settings.z[0] <= z <= settings.z[1]
    # the same seed, the same moves: a seeded simulation repeats
    again = Seat(T0, "ann:seat")
    assert [again.face(T0 + timedelta(seconds=s)) for s in range(0, 1800, 1)] == faces


def test_a_scripted_move_goes_smoothly_from_where_the_face_is() -> None:
    seat = Seat(T0, 1, SeatSettings(still_s=(1e6, 1e6)))
    seat.move_to((0.6, 0.3, 0.3), T0, seconds=2.0)
    assert seat.face(T0 + timedelta(seconds=1))[1] == pytest.approx(0.15)
    assert seat.face(T0 + timedelta(seconds=3)) == (0.6, 0.3, 0.3)


def _aim(command_id: str, joints: dict[str, float], action: str = "look_at") -> RobotCommand:
    return RobotCommand(id=command_id, channel="aim", action=action, args={"joints": joints})


def test_the_sim_robot_turns_at_the_joints_speed_and_reports_done_when_there() -> None:
    robot = SimRobot()
    robot.send(_aim("a1", {"neck": 0.8, "head": 0.2}), T0)
    takes = 0.8 / JOINTS["neck"].speed
    halfway = robot.joints(T0 + timedelta(seconds=takes / 2))
    assert halfway["neck"] == pytest.approx(0.4)
    assert [f.status for f in robot.poll(T0 + timedelta(seconds=takes / 2))] == ["started"]
    done = robot.poll(T0 + timedelta(seconds=takes + 0.01))
    assert [f.status for f in done] == ["done"]
    assert robot.joints(T0 + timedelta(seconds=takes + 0.01))["neck"] == pytest.approx(0.8)


def test_an_aim_beyond_a_limit_stops_at_it_and_an_interrupt_holds_the_joints() -> None:
    robot = SimRobot()
    robot.send(_aim("a1", {"neck": 3.0}), T0)  # the neck turns one radian at most
    assert robot.joints(T0 + timedelta(seconds=5))["neck"] == pytest.approx(JOINTS["neck"].high)
    robot.send(_aim("a2", {"neck": -1.0}), T0 + timedelta(seconds=5))
    robot.interrupt("a2", T0 + timedelta(seconds=5.5))
    held = robot.joints(T0 + timedelta(seconds=5.5))["neck"]
    assert robot.joints(T0 + timedelta(seconds=9))["neck"] == pytest.approx(held)
    assert held == pytest.approx(JOINTS["neck"].high - 0.5 * JOINTS["neck"].speed)


def test_a_robot_ignores_joints_it_does_not_have() -> None:
    robot = SimRobot()
    robot.send(_aim("a1", {"tail": 1.0, "neck": "left"}), T0)  # type: ignore[dict-item]
    assert robot.joints(T0 + timedelta(seconds=1)) == {name: 0.0 for name in JOINTS}
    assert [f.status for f in robot.poll(T0 + timedelta(seconds=1))] == ["started", "done"]
