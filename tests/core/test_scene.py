"""Frames from perception, through the input board as the daemon
takes them each tick; the optional inputs' messages and the aim channel's best effort."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

import pytest
from pydantic import ValidationError

from dms.inputs import InputBoard, InputRejected, parse_input
from dms.kernel import keys
from dms.kernel.expression import CommandStatus, ExpressionArbiter
from dms.kernel.frames import UnknownFrame
from dms.kernel.messages import ObjectsPerception, RobotJoints, UserPerception
from dms.scene import USER_FRAME, Scene
from sim.robot import SimRobot

T0 = datetime(2026, 11, 24, 10, 0, tzinfo=UTC)


def _user(y: float, user_id: str | None = "ann") -> UserPerception:
    return UserPerception.model_validate(
        {
            "present": True,
            "user_id": user_id,
            "ready": True,
            "face": {"position": {"x": 0.6, "y": y, "z": 0.35}},
        }
    )


class Ticking:
    """An input board and a scene, ticked as the controller does (monotonic = seconds)."""

    def __init__(self, stale_after_s: float = 2.0) -> None:
        self.board = InputBoard()
        self.scene = Scene(face_live_s=stale_after_s, object_live_s=stale_after_s)
        self.t = 0.0

    def feed(self, key: str, message: object) -> None:
        self.board.accept(key, message, self.t)  # type: ignore[arg-type]

    def tick(self, seconds: float = 0.5) -> datetime:
        self.t += seconds
        snapshot = self.board.take(self.t)
        now = T0 + timedelta(seconds=self.t)
        self.scene.update(snapshot.values, snapshot.fresh, now)
        return now


def test_a_face_in_perception_becomes_the_user_frame_and_the_named_face() -> None:
    run = Ticking()
    run.feed(keys.PERCEPTION_USER, _user(0.2))
    now = run.tick()
    for frame in (USER_FRAME, "face:ann"):
        located = run.scene.frames.lookup(frame, now)
        assert located.live and located.position == pytest.approx((0.6, 0.2, 0.35))


def test_a_refreshed_face_stays_live_and_an_unrefreshed_one_becomes_last_known() -> None:
    run = Ticking(stale_after_s=2.0)
    message = _user(0.1)
    for _ in range(10):  # the same message refreshed every tick: a frozen, unchanged face
        run.feed(keys.PERCEPTION_USER, message)
        now = run.tick()
    assert run.scene.frames.lookup(USER_FRAME, now).live
    for _ in range(5):  # nothing for 2.5 s: the last known pose, with its age
        now = run.tick()
    located = run.scene.frames.lookup(USER_FRAME, now)
    assert not located.live and located.age_s == pytest.approx(2.5)
    assert located.position == pytest.approx((0.6, 0.1, 0.35))


def test_a_perception_without_a_face_does_not_move_or_renew_the_frame() -> None:
    run = Ticking(stale_after_s=1.0)
    run.feed(keys.PERCEPTION_USER, _user(-0.2))
    run.tick()
    faceless = UserPerception(present=True, user_id="ann", ready=True)
    for _ in range(4):
        run.feed(keys.PERCEPTION_USER, faceless)
        now = run.tick()
    located = run.scene.frames.lookup("face:ann", now)
    assert not located.live and located.position[1] == pytest.approx(-0.2)


def test_objects_are_frames_and_one_no_longer_seen_keeps_its_last_pose() -> None:
    run = Ticking(stale_after_s=1.0)
    both = ObjectsPerception.model_validate(
        {
            "objects": [
                {"name": "cup", "pose": {"position": {"x": 0.4, "y": -0.1, "z": 0.05}}},
                {
                    "name": "tag7",
                    "pose": {
                        "position": {"x": 0.5, "y": 0.3, "z": 0.1},
                        "orientation": {"x": 0.0, "y": 0.0, "z": 0.7071068, "w": 0.7071068},
                    },
                },
            ]
        }
    )
    run.feed(keys.PERCEPTION_OBJECTS, both)
    run.tick()
    only_cup = ObjectsPerception.model_validate({"objects": [both.objects[0].model_dump()]})
    for _ in range(4):
        run.feed(keys.PERCEPTION_OBJECTS, only_cup)
        now = run.tick()
    assert run.scene.frames.lookup("object:cup", now).live
    tag = run.scene.frames.lookup("object:tag7", now)
    assert not tag.live and tag.position == pytest.approx((0.5, 0.3, 0.1))
    # the tag's orientation counts: its x axis points to the base's +y (a quarter turn)
    assert tag.matrix[:3, 0] == pytest.approx((0.0, 1.0, 0.0), abs=1e-6)
    with pytest.raises(UnknownFrame):
        run.scene.frames.lookup("object:ball", now)


def test_an_external_robots_joints_move_the_body_frames() -> None:
    run = Ticking()
    run.feed(keys.ROBOT_JOINTS, RobotJoints.model_validate({"positions": {"neck": 0.5}}))
    now = run.tick()
    assert run.scene.joints["neck"] == 0.5
    head = run.scene.frames.lookup("head", now)
    assert head.position[1] > 0.0  # the head turned left: its camera is left of centre


def test_optional_inputs_appear_in_the_state_only_once_provided() -> None:
    board = InputBoard()
    assert keys.PERCEPTION_OBJECTS not in board.take(0.0).status
    board.accept(keys.PERCEPTION_OBJECTS, ObjectsPerception(objects=[]), 1.0)
    assert board.take(1.0).status[keys.PERCEPTION_OBJECTS] == "ok"
    assert board.take(7.0).status[keys.PERCEPTION_OBJECTS] == "stale"


@pytest.mark.parametrize(
    ("key", "payload", "reason"),
    [
        (
            "perception/user",
            b'{"present": true, "face": {"position": {"x": 1e9, "y": 0, "z": 0}}}',
            "face.position.x",
        ),
        (
            "perception/user",
            b'{"present": true, "face": {"position": {"x": 1, "y": 0}}}',
            "face.position.z",
        ),
        (
            "perception/user",
            b'{"present": true, "face": {"position": {"x": 1, "y": 0, "z": 0},'
            b' "orientation": {"x": 0, "y": 0, "z": 0, "w": 0}}}',
            "zero quaternion",
        ),
        (
            "perception/objects",
            b'{"objects": [{"name": "Bad Name!", "pose": {"position": {"x": 0, "y": 0, "z": 0}}}]}',
            "objects.0.name",
        ),
        ("robot/joints", b'{"positions": {"elbow": 0.1}}', "unknown joint 'elbow'"),
        ("robot/joints", b'{"positions": {"neck": "left"}}', "positions.neck"),
    ],
)
def test_malformed_frames_are_rejected_with_one_line_naming_the_field(
    key: str, payload: bytes, reason: str
) -> None:
    with pytest.raises(InputRejected) as caught:
        parse_input(key, payload)
    line = str(caught.value)
    assert "\n" not in line and reason in line, line


def test_an_aim_the_robot_never_acknowledges_does_not_make_it_offline() -> None:
    robot = SimRobot()
    robot.set_fault("aim", "hang")
    arbiter = ExpressionArbiter(robot, lambda _c: None, ack_timeout_s=1.0, offline_after_unacked=3)
    now = T0
    aims = []
    for _ in range(5):
        aims.append(
            arbiter.request("activity:talk", "aim", "look_at", {"joints": {"neck": 0.3}}, now)
        )
        now += timedelta(seconds=1.5)
        arbiter.update(now)
    assert all(handle.status is CommandStatus.TIMED_OUT for handle in aims)
    assert not arbiter.robot_offline
    # and a gesture is never held up behind an unanswered aim: its own lane
    aim = arbiter.request("activity:talk", "aim", "look_at", {"joints": {"neck": 0.3}}, now)
    nod = arbiter.request("activity:talk", "motion", "gesture", {"name": "nod"}, now)
    assert aim.status is CommandStatus.SENT and nod.status is CommandStatus.SENT


def test_a_joint_message_is_validated_as_a_whole() -> None:
    with pytest.raises(ValidationError):
        RobotJoints.model_validate({"positions": {"head": float("nan")}})


def test_a_detector_inventing_names_cannot_grow_the_frames_without_bound() -> None:
    """Months beside a tag detector that misreads: the scene keeps the 256 frames seen
    most recently, and the one in use stays."""
    from dms.scene import MAX_PERCEIVED

    run = Ticking()
    ann = _user(0.1)  # one frozen message, refreshed: the face is only restamped
    for index in range(2_000):
        run.feed(keys.PERCEPTION_USER, ann)
        message = ObjectsPerception.model_validate(
            {"objects": [{"name": f"junk{index}", "pose": {"position": {"x": 1, "y": 0, "z": 0}}}]}
        )
        run.feed(keys.PERCEPTION_OBJECTS, message)
        now = run.tick()
    perceived = [n for n in run.scene.frames.names if n.startswith(("object:", "face:"))]
    assert len(perceived) == MAX_PERCEIVED
    assert "object:junk1999" in perceived and "object:junk0" not in perceived
    assert run.scene.frames.lookup("face:ann", now).live
