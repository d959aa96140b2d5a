"""A user id the store does not know becomes a profile only once it has been ready and
engaged for ``new_user_after_s``, and no more than ``new_profiles_per_hour`` an hour.

A real controller on a virtual clock (the simulated Mini) over a real SQLite file: the
users and sessions tables are read back from the store.
"""

from __future__ import annotations

from collections.abc import Iterator
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

import pytest

from dms.config import Settings
from dms.kernel import keys
from dms.kernel.messages import Request, UserPerception
from sim.harness import Simulation

START = datetime(2026, 11, 24, 10, 0, tzinfo=UTC)


def _robot(db: Path, start: datetime = START, **controller: Any) -> Simulation:
    settings = Settings.model_validate(
        {
            "db": f"sqlite:///{db}",
            "controller": {
                "session_questions": 0,
                "question_every": 0,
                "feedback_probability": 0.0,
                **controller,
            },
        }
    )
    return Simulation(settings, seed=3, start=start)


@pytest.fixture
def robot(tmp_path: Path) -> Iterator[Simulation]:
    with _robot(tmp_path / "dms.db") as sim:
        yield sim


def _show(sim: Simulation, user_id: str, engagement: float | None = 0.8) -> None:
    sim.presence = UserPerception(present=True, user_id=user_id, ready=True, engagement=engagement)
    sim.feed(keys.PERCEPTION_USER, sim.presence)


def _nobody(sim: Simulation) -> None:
    sim.presence = UserPerception(present=False, user_id=None, ready=False, engagement=None)
    sim.feed(keys.PERCEPTION_USER, sim.presence)


def _stored(sim: Simulation) -> list[str]:
    assert sim.stack.store is not None
    return sim.stack.store.list_ids()


def _sessions(sim: Simulation) -> list[dict[str, Any]]:
    assert sim.stack.store is not None
    return sim.stack.store.sessions()


def test_the_default_waits_a_few_seconds_and_caps_new_profiles_at_20_an_hour() -> None:
    settings = Settings().controller
    assert 0 < settings.new_user_after_s <= 5
    assert settings.new_profiles_per_hour == 20


def test_a_flood_of_ids_seen_for_a_tick_each_stores_nothing(robot: Simulation) -> None:
    for index in range(200):
        _show(robot, f"ghost{index}")
        robot.run_for(0.5)
    assert robot.controller.sessions.session is not None  # served as a new user meanwhile
    _nobody(robot)
    robot.run_for(2)
    assert _stored(robot) == []
    assert _sessions(robot) == []
    assert not robot.errors  # nobody went over the hourly cap: nothing to report


def test_a_user_ready_and_engaged_long_enough_gets_her_profile_and_whole_session(
    robot: Simulation,
) -> None:
    _show(robot, "ann")
    robot.run_for(1)
    robot.feed(keys.REQUEST, Request(action="start", activity="weather", by="ann"))
    robot.run_for(1)
    assert _stored(robot) == []  # not yet: 2 s of the 3
    robot.run_for(2)
    assert _stored(robot) == ["ann"]
    sessions = _sessions(robot)
    assert [s["user"] for s in sessions] == ["ann"]
    # the session is stored as of when she became ready, not when she qualified
    assert datetime.fromisoformat(sessions[0]["started"]).replace(tzinfo=UTC) == START
    _nobody(robot)
    robot.run_for(6)
    assert robot.stack.store is not None
    runs = robot.stack.store.export("ann")["activities"]
    assert [run["activity"] for run in runs] == ["weather"]  # held, then written
    assert runs[0]["session_id"] == sessions[0]["session"]
    assert _sessions(robot)[0]["ended"] is not None


def test_a_user_who_leaves_before_qualifying_leaves_nothing_behind(robot: Simulation) -> None:
    _show(robot, "bob")
    robot.run_for(1)
    robot.feed(keys.REQUEST, Request(action="start", activity="weather", by="bob"))
    robot.run_for(1)
    _nobody(robot)
    robot.run_for(10)
    assert _stored(robot) == []
    assert _sessions(robot) == []


def test_disengagement_restarts_the_wait(robot: Simulation) -> None:
    _show(robot, "cid")
    robot.run_for(2.5)
    _show(robot, "cid", engagement=0.0)
    robot.run_for(1)
    _show(robot, "cid", engagement=None)  # unknown engagement does not count against her
    robot.run_for(2.5)
    assert _stored(robot) == []
    robot.run_for(1)
    assert _stored(robot) == ["cid"]


def test_a_known_user_is_stored_at_once(tmp_path: Path) -> None:
    db = tmp_path / "dms.db"
    with _robot(db) as first:
        _show(first, "dee")
        first.run_for(4)
        _nobody(first)
        first.run_for(2)
    with _robot(db, START + timedelta(hours=2)) as second:
        _show(second, "dee")
        second.run_for(0.5)
        assert len(_sessions(second)) == 2


def test_the_hourly_cap_refuses_the_rest_and_reports_them_once_with_their_count(
    tmp_path: Path,
) -> None:
    with _robot(tmp_path / "dms.db", new_user_after_s=1.0, new_profiles_per_hour=2) as sim:
        for index in range(6):
            _show(sim, f"visitor{index}")
            sim.run_for(2)
        sim.run_for(10)
        assert _stored(sim) == ["visitor0", "visitor1"]
        reports = [error for _, key, error in sim.errors if key == keys.PERCEPTION_USER]
        assert len(reports) == 1, sim.errors
        assert reports[0].startswith("4 new user ids not stored in the last ")
        assert "new_profiles_per_hour = 2" in reports[0]
        # an hour after the first ones, new profiles are made again
        sim.run_for(3600)
        _show(sim, "visitor9")
        sim.run_for(2)
        assert "visitor9" in _stored(sim)


def test_without_the_wait_a_new_user_is_stored_in_her_first_tick(tmp_path: Path) -> None:
    with _robot(tmp_path / "dms.db", new_user_after_s=0) as sim:
        _show(sim, "eve")
        sim.run_for(0.5)
        assert _stored(sim) == ["eve"]
        assert len(_sessions(sim)) == 1
