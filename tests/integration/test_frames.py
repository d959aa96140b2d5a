"""From outside: a real daemon over real Zenoh turns toward the person it plays with.

A perception process (this test) publishes ``perception/user`` with the face's position
five times a second; the daemon runs the quiz, whose behavior attends to the user, and
its simulated Mini reports its joints on ``robot/joints``. The face moves from the left
to the right: the neck follows, never faster than its top speed. The face is lost (the
person turned away; perception goes on without a face): the head returns to neutral
once the frame has been last-known for the behavior's ``neutral_after_s``. Then the
simulated Mini as its own Zenoh process (``--robot zenoh``): it executes the aim
commands and reports its joints, which the daemon follows.
"""

from __future__ import annotations

import itertools
import math
import threading
from datetime import datetime
from pathlib import Path
from typing import Any

import pytest
import zenoh

from dms.bus import ZenohClient, make_config
from dms.kernel.body import JOINTS
from dms.kernel.clock import RealClock
from sim.robot_node import RobotNode
from tests.integration.harness import (
    Collector,
    put,
    running_daemon,
    wait_token,
)

pytestmark = pytest.mark.integration

X, Z = 0.6, 0.35
LEFT, RIGHT = 0.35, -0.35
NECK_LEFT = math.atan2(LEFT, X)  # 0.53 rad: within the neck's range, no hip needed


class Perception:
    """A perception module: ``perception/user`` at 5 Hz with the face where it is now."""

    def __init__(self, session: zenoh.Session) -> None:
        self.session = session
        self.face: dict[str, float] | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        while not self._stop.wait(0.2):
            message: dict[str, Any] = {"present": True, "user_id": "ann", "ready": True}
            if self.face is not None:
                message["face"] = {"position": dict(self.face)}
            put(self.session, "perception/user", message)

    def __enter__(self) -> Perception:
        self._thread.start()
        return self

    def __exit__(self, *_exc: object) -> None:
        self._stop.set()
        self._thread.join(5.0)


def _time(message: dict[str, Any]) -> float:
    return datetime.fromisoformat(message["time"].replace("Z", "+00:00")).timestamp()


FACE_LIVE_1S = "[frames]\nface_live_s = 1.0\n"


def test_the_head_follows_a_face_from_left_to_right_at_the_necks_speed(tmp_path: Path) -> None:
    with running_daemon(tmp_path, FACE_LIVE_1S) as (daemon, session):
        joints = Collector(session, "robots/mini/robot/joints")
        commands = Collector(session, "robots/mini/robot/command")
        with Perception(session) as perception:
            perception.face = {"x": X, "y": LEFT, "z": Z}
            put(session, "request", {"action": "start", "activity": "quiz", "by": "test"})
            left = joints.wait_for(
                lambda m: abs(m["positions"]["neck"] - NECK_LEFT) < 0.02, timeout=20.0
            )
            aim = commands.wait_for(
                lambda c: c["channel"] == "aim" and c["args"]["frame"] is not None, timeout=5.0
            )
            assert aim["action"] == "look_at" and aim["args"]["frame"] == "user"
            assert aim["args"]["position"] == pytest.approx({"x": X, "y": LEFT, "z": Z})

            mark = joints.mark()
            perception.face = {"x": X, "y": RIGHT, "z": Z}
            right = joints.wait_for(
                lambda m: abs(m["positions"]["neck"] + NECK_LEFT) < 0.02, timeout=20.0, start=mark
            )
            # The turn is a motor's, not a jump: never faster than the neck's top speed,
            # and so at least as long as the angle over that speed.
            samples = joints.messages[mark : joints.messages.index(right) + 1]
            speed = JOINTS["neck"].speed
            for before, after in itertools.pairwise(samples):
                dt = _time(after) - _time(before)
                if dt > 0.05:  # a sample's time has millisecond resolution
                    moved = abs(after["positions"]["neck"] - before["positions"]["neck"])
                    assert moved <= speed * dt * 1.1 + 0.01, (before, after)
            assert _time(right) - _time(left) >= 2 * NECK_LEFT / speed - 0.05
            # The head tilted down toward a face below its eyes, within its limits.
            assert 0.0 < right["positions"]["head"] <= JOINTS["head"].high

            # The person turns away: perception goes on, without a face. The frame is
            # live 1 s more ([frames] face_live_s), then last known; the quiz's attend
            # holds the gaze until the face has not been seen for 3 s (neutral_after_s),
            # then looks ahead again.
            lost = joints.mark()
            perception.face = None
            neutral = joints.wait_for(
                lambda m: abs(m["positions"]["neck"]) < 0.01, timeout=20.0, start=lost
            )
            since = _time(joints.messages[lost])
            held = [m for m in joints.messages[lost:] if _time(m) < since + 2.5]
            assert held and all(abs(m["positions"]["neck"] + NECK_LEFT) < 0.02 for m in held)
            assert _time(neutral) - since >= 3.0 - 0.25  # the last face came up to 0.2 s before
        assert daemon.terminate() == 0


def test_the_simulated_mini_over_zenoh_turns_and_reports_its_joints(tmp_path: Path) -> None:
    with running_daemon(tmp_path, FACE_LIVE_1S, ("--robot", "zenoh")) as (daemon, session):
        robot_client = ZenohClient("mini", make_config(connect=[f"tcp/127.0.0.1:{daemon.port}"]))
        node = RobotNode(robot_client, RealClock(), seed=2)
        thread = threading.Thread(target=node.run, daemon=True)
        joints = Collector(session, "robots/mini/robot/joints")
        states = Collector(session, "robots/mini/dms/state")
        try:
            thread.start()
            wait_token(session, "robots/mini/alive/robot/joints", timeout=10.0)
            with Perception(session) as perception:
                perception.face = {"x": X, "y": LEFT, "z": Z}
                put(session, "request", {"action": "start", "activity": "quiz", "by": "test"})
                turned = joints.wait_for(
                    lambda m: abs(m["positions"]["neck"] - NECK_LEFT) < 0.02, timeout=20.0
                )
                assert set(turned["positions"]) == set(JOINTS)
                # the daemon takes the robot's joints as an input, and shows it in the state
                states.wait_for(lambda s: s["inputs"].get("robot/joints") == "ok", timeout=10.0)
        finally:
            node.stopped.set()
            thread.join(5.0)
            robot_client.close()
        # every joint state seen came from the robot's process: the daemon publishes none
        assert 0 < len(joints.messages) <= node.joint_states
        assert daemon.terminate() == 0
