"""Blocks that take frames as targets, on the simulated Mini.

The frames are a real :class:`FrameStore` kept as the daemon's scene keeps it (faces and
objects with their times, the body from the simulated Mini's joints); the commands go
through the expression arbiter to the simulated Mini, whose joints move at their speeds.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from datetime import timedelta
from pathlib import Path
from typing import Any

import pytest

from activities import Activity, ActivityContext, ActivityStatus, BehaviorError, BehaviorLibrary
from activities.spec import parse_text
from dms.kernel import keys
from dms.kernel.body import JOINTS
from dms.kernel.frames import FrameStore, pose
from dms.kernel.gaze import EYE_HEIGHT_M
from dms.kernel.messages import UserPerception
from dms.scene import Scene
from tests.activities.conftest import Bench, write_behaviors

FACE_X = 0.6


class GazeBench(Bench):
    """A bench whose activities see the frames, and whose robot reports its joints."""

    def __init__(self, library: BehaviorLibrary | None = None) -> None:
        super().__init__(library)
        self.scene = Scene(face_live_s=1.0, object_live_s=1.0, joints=self.robot.joints)
        self.frames: FrameStore = self.scene.frames

    def context(self, name: str = "test") -> ActivityContext:
        ctx = super().context(name)
        ctx.frames = self.frames
        ctx.joints = self.scene.joints
        return ctx

    def face(self, y: float, z: float = EYE_HEIGHT_M) -> None:
        """The user's face is seen now at (FACE_X, y, z)."""
        self.frames.set("user", pose((FACE_X, y, z)), stamp=self.now, stale_after_s=1.0)

    def step(self, activity: Activity, seconds: float = 0.5) -> None:
        self.now += timedelta(seconds=seconds)
        self.scene.update({}, frozenset(), self.now)
        self.expression.update(self.now)
        activity.tick(self.now)

    def joints(self) -> Mapping[str, float]:
        return self.robot.joints(self.now)

    def aims(self) -> list[dict[str, Any]]:
        return [dict(c.args) for c in self.commands if c.channel == "aim"]


def _bench(tmp_path: Path, files: Mapping[str, str]) -> GazeBench:
    return GazeBench(BehaviorLibrary.load(write_behaviors(tmp_path / "behaviors", files)))


LOOK = """
    name: look
    outcomes: [done, lost]
    states:
      LOOK:
        look_at: {frame: "object:cup", last_known: %s}
"""


def test_look_at_turns_toward_a_frame_within_the_joints_limits(tmp_path: Path) -> None:
    bench = _bench(tmp_path, {"look": LOOK % "true"})
    bench.frames.set("object:cup", pose((0.3, 0.6, 0.0)), stamp=bench.now, stale_after_s=1.0)
    activity = bench.start(bench.create("look"))
    assert bench.finish(activity, limit_s=5) is ActivityStatus.COMPLETED
    assert activity.result.outcome == "done"
    joints = bench.joints()
    yaw = math.atan2(0.6, 0.3)  # 1.107 rad: more than the neck's 1.0, so the hip helps
    assert joints["neck"] + joints["hip"] == pytest.approx(yaw, abs=1e-3)
    assert joints["head"] == pytest.approx(JOINTS["head"].high)  # down to the table, at the limit
    assert bench.aims()[0]["live"] is True


def test_look_at_uses_the_last_known_pose_or_ends_lost(tmp_path: Path) -> None:
    """ROS Commander's task frames: no live estimate, the last known one, if the behavior says."""
    for last_known, outcome in (("true", "done"), ("false", "lost")):
        bench = _bench(tmp_path / last_known, {"look": LOOK % last_known})
        bench.frames.set("object:cup", pose((0.5, -0.2, 0.1)), stamp=bench.now, stale_after_s=1.0)
        bench.now += timedelta(seconds=30)  # the cup was taken out of sight 30 s ago
        activity = bench.start(bench.create("look"))
        bench.finish(activity, limit_s=5)
        assert activity.result.outcome == outcome
        if outcome == "done":
            assert bench.aims()[0]["live"] is False
            assert bench.aims()[0]["position"] == {"x": 0.5, "y": -0.2, "z": 0.1}
            assert bench.joints()["neck"] == pytest.approx(math.atan2(-0.2, 0.5), abs=1e-3)
        else:
            assert bench.aims() == []
    never = _bench(tmp_path / "never", {"look": LOOK % "true"})  # never seen at all
    activity = never.start(never.create("look"))
    never.finish(activity, limit_s=5)
    assert activity.result.outcome == "lost"


def test_point_at_raises_the_arm_on_the_objects_side(tmp_path: Path) -> None:
    bench = _bench(
        tmp_path,
        {
            "point": """
                name: point
                outcomes: [done, lost]
                states:
                  POINT:
                    point_at: {frame: "object:tag"}
            """
        },
    )
    bench.frames.set("object:tag", pose((0.5, 0.2, 0.34)), stamp=bench.now, stale_after_s=1.0)
    activity = bench.start(bench.create("point"))
    bench.finish(activity, limit_s=5)
    joints = bench.joints()
    assert joints["left_arm"] == pytest.approx(math.pi / 2, abs=0.01)  # level: straight out
    assert joints["right_arm"] == 0.0
    assert joints["hip"] == pytest.approx(math.atan2(0.2, 0.5), abs=1e-3)


ATTEND_WHILE_TALKING = """
    name: chat
    outcomes: [done]
    states:
      TOGETHER:
        concurrence:
          outcomes: [done]
          default_outcome: done
          outcome_map: {done: {TALK: done}}
          states:
            TALK:
              wait: {seconds: 60}
            GAZE:
              attend: {frame: user, neutral_after_s: 2}
        transitions: {done: done}
"""


def test_attend_follows_the_face_at_the_necks_speed_without_jitter(tmp_path: Path) -> None:
    bench = _bench(tmp_path, {"chat": ATTEND_WHILE_TALKING})
    bench.face(0.3)
    activity = bench.start(bench.create("chat"))
    for _ in range(10):
        bench.face(0.3 + (0.005 if _ % 2 else -0.005))  # a tracker's noise: 1 cm
        bench.step(activity)
    left = math.atan2(0.3, FACE_X)
    assert bench.joints()["neck"] == pytest.approx(left, abs=0.02)
    shifts = len(bench.aims())
    assert shifts == 1  # the noise was within the dead band: no jitter
    # The user moves from the left to the right; the head follows at the neck's speed.
    positions = []
    for _ in range(8):
        bench.face(-0.3)
        bench.step(activity, 0.25)
        positions.append(bench.joints()["neck"])
    speed = JOINTS["neck"].speed
    for before, after in zip([left, *positions], positions, strict=False):
        assert abs(after - before) <= speed * 0.25 + 1e-9
    assert positions[-1] == pytest.approx(-left, abs=0.02)
    assert activity.status is ActivityStatus.RUNNING


def test_attend_holds_the_gaze_then_returns_to_neutral_once_the_face_is_gone(
    tmp_path: Path,
) -> None:
    bench = _bench(tmp_path, {"chat": ATTEND_WHILE_TALKING})
    bench.face(0.3)
    activity = bench.start(bench.create("chat"))
    for _ in range(4):
        seen = bench.now
        bench.face(0.3)
        bench.step(activity)
    looking = bench.joints()["neck"]
    assert looking > 0.4
    while bench.now < seen + timedelta(seconds=1.9):  # not seen, not yet 2 s: held
        bench.step(activity, 0.1)
        assert bench.joints()["neck"] == pytest.approx(looking)
    for _ in range(10):
        bench.step(activity, 0.1)
    assert bench.joints() == pytest.approx({name: 0.0 for name in JOINTS})
    assert bench.aims()[-1]["frame"] is None


def test_a_paused_activity_stops_aiming_and_looks_again_when_resumed(tmp_path: Path) -> None:
    bench = _bench(tmp_path, {"chat": ATTEND_WHILE_TALKING})
    bench.face(0.3)
    activity = bench.start(bench.create("chat"))
    bench.step(activity)
    activity.pause(bench.now)
    before = len(bench.aims())
    for _ in range(6):
        bench.face(-0.3)
        bench.step(activity)
    assert len(bench.aims()) == before  # paused: the notification has the robot now
    activity.resume(bench.now)
    for _ in range(6):
        bench.face(-0.3)
        bench.step(activity)
    assert bench.joints()["neck"] == pytest.approx(-math.atan2(0.3, FACE_X), abs=0.02)


def test_a_gesture_toward_a_frame_is_retargeted_when_the_frame_moves(tmp_path: Path) -> None:
    bench = _bench(
        tmp_path,
        {
            "wave": """
                name: wave
                outcomes: [done]
                states:
                  WAVE:
                    gesture: {name: dance_step, toward: user}
            """
        },
    )
    bench.face(0.0)
    activity = bench.start(bench.create("wave"))
    bench.step(activity)
    assert bench.aims()[0]["joints"] == {"hip": 0.0}
    bench.face(0.4)  # she moves her chair to the robot's left while it dances
    bench.step(activity)
    turns = [a for a in bench.aims() if a["joints"].keys() == {"hip"}]
    assert turns[-1]["joints"]["hip"] == pytest.approx(math.atan2(0.4, FACE_X), abs=1e-3)
    assert bench.finish(activity, limit_s=10) is ActivityStatus.COMPLETED


def test_a_robot_that_ignores_aims_loses_nothing(tmp_path: Path) -> None:
    """An older robot: the aim channel never answers. The reminder still plays at once
    after the turn's time, the activity completes, and the robot stays online."""
    bench = GazeBench(BehaviorLibrary.load())
    bench.robot.set_fault("aim", "hang")
    bench.face(0.3)
    activity = bench.start(bench.create("notification", {"text": "Time for your pills."}))
    bench.run_until(activity, lambda: "Time for your pills." in bench.said(), limit_s=3)
    assert bench.finish(activity, limit_s=30) is ActivityStatus.COMPLETED
    assert not bench.expression.robot_offline


def test_the_shipped_reminder_turns_toward_the_person_before_it_speaks() -> None:
    bench = GazeBench(BehaviorLibrary.load())
    bench.face(-0.35)
    activity = bench.start(bench.create("notification", {"text": "Lunch is ready."}))
    bench.finish(activity, limit_s=30)
    channels = [c.channel for c in bench.commands]
    assert channels.index("aim") < channels.index("speech")
    assert bench.commands[channels.index("aim")].args["frame"] == "user"


@pytest.mark.parametrize("name", ["talk", "quiz", "bingo"])
def test_the_shipped_talk_quiz_and_bingo_look_at_the_person(name: str) -> None:
    bench = GazeBench(BehaviorLibrary.load())
    bench.face(0.25)
    activity = bench.start(bench.create(name))
    for _ in range(6):
        bench.face(0.25)
        bench.step(activity)
    assert bench.joints()["neck"] == pytest.approx(math.atan2(0.25, FACE_X), abs=0.02)


@pytest.mark.parametrize(
    ("attend", "message"),
    [
        ("attend: 5\n", "attend: must be a frame's name or a mapping"),
        ("attend: {frame: user, speed: 3}\n", "attend: unknown parameter 'speed'"),
        ("attend: {neutral_after_s: -1}\n", "attend: parameter 'neutral_after_s'"),
    ],
)
def test_a_wrong_attend_is_refused_with_its_line(attend: str, message: str) -> None:
    text = "name: x\n" + attend + "outcomes: [done]\nstates:\n  A:\n    wait: {seconds: 1}\n"
    with pytest.raises(BehaviorError) as caught:
        parse_text(text, "x.yaml")
    assert str(caught.value).startswith("x.yaml:2:") and message in str(caught.value)


def test_a_face_refreshed_unchanged_sends_nothing_and_its_loss_is_still_seen(
    tmp_path: Path,
) -> None:
    """The gaze keeper skips its work while nothing moved and the face is live; that
    shortcut must not hide the face going stale (no refresh) or moving."""
    bench = _bench(tmp_path, {"chat": ATTEND_WHILE_TALKING})
    seen = UserPerception.model_validate(
        {"present": True, "user_id": "ann", "face": {"position": {"x": FACE_X, "y": 0.3, "z": 0.4}}}
    )
    activity = bench.start(bench.create("chat"))

    def tick(message: UserPerception | None) -> None:
        bench.now += timedelta(seconds=0.5)
        values = {keys.PERCEPTION_USER: message} if message is not None else {}
        fresh = frozenset(values)
        bench.scene.update(values, fresh, bench.now)
        bench.expression.update(bench.now)
        activity.tick(bench.now)

    for _ in range(40):  # 20 s of the same face, refreshed at every tick
        tick(seen)
    assert len(bench.aims()) == 2  # neutral at the start (nothing seen yet), then the face
    assert bench.joints()["neck"] == pytest.approx(math.atan2(0.3, FACE_X), abs=0.02)
    moved = UserPerception.model_validate(
        {
            "present": True,
            "user_id": "ann",
            "face": {"position": {"x": FACE_X, "y": -0.3, "z": 0.4}},
        }
    )
    for _ in range(4):
        tick(moved)
    assert bench.joints()["neck"] == pytest.approx(-math.atan2(0.3, FACE_X), abs=0.02)
    for _ in range(12):  # no refresh: live 1 s more, then neutral 2 s after it was seen
        tick(None)
    assert bench.joints()["neck"] == pytest.approx(0.0)
