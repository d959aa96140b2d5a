"""The scene: the robot's frames, kept current from what it perceives and its joints.

Each tick the controller hands :meth:`Scene.update` the inputs that are ok. A new
``perception/user`` with a ``face`` moves the frames ``user`` (whoever is in front)
and ``face:<user_id>``; a new ``perception/objects`` moves ``object:<name>`` for each
object seen. A frame is *live* while its input is fresh (the input's ``stale_after_s``)
and *last known* after, with its age: behaviors choose what to do with an old pose
(seed 002's task frames). The body's frames follow the joint state: the simulated
Mini's own, or the external robot's ``robot/joints``.

Pure and on the caller's clock, like the motivation model: nothing here reads time.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from datetime import datetime

from pydantic import BaseModel

from dms.kernel import keys
from dms.kernel.body import NEUTRAL, body_frames
from dms.kernel.frames import BASE, FACE_PREFIX, OBJECT_PREFIX, FrameStore, Matrix, pose
from dms.kernel.messages import ObjectsPerception, Pose, RobotJoints, UserPerception

USER_FRAME = "user"
"""The face of whoever is in front of the robot: what ``attend`` and ``look_at`` follow
by default."""

DEFAULT_STALE_AFTER_S = 5.0

JointSource = Callable[[datetime], Mapping[str, float]]
"""The joint state at ``now`` of a robot in the same process (the simulated Mini)."""


def matrix_of(where: Pose) -> Matrix:
    """The transform of a perceived pose (no orientation: only a position)."""
    p = where.position
    q = where.orientation
    return pose((p.x, p.y, p.z), quaternion=None if q is None else (q.x, q.y, q.z, q.w))


class Scene:
    """The frame store and what keeps it current; one per controller."""

    def __init__(
        self,
        stale_after_s: Mapping[str, float | None] | None = None,
        joints: JointSource | None = None,
    ) -> None:
        limits = stale_after_s or {}
        self.face_stale_after_s = _limit(limits, keys.PERCEPTION_USER)
        self.object_stale_after_s = _limit(limits, keys.PERCEPTION_OBJECTS)
        self.frames = FrameStore(body_frames(NEUTRAL))
        self.joints: dict[str, float] = dict(NEUTRAL)
        """The joint state the body frames were last set from."""
        self._joint_source = joints
        self._seen_user: BaseModel | None = None
        self._seen_objects: BaseModel | None = None
        self._seen_joints: BaseModel | None = None

    def update(self, values: Mapping[str, BaseModel], now: datetime) -> None:
        """Move the frames from this tick's inputs (those that are ok)."""
        user = values.get(keys.PERCEPTION_USER)
        if user is not self._seen_user and isinstance(user, UserPerception):
            self._seen_user = user
            if user.present and user.face is not None:
                self.see_face(user.user_id, user.face, now)
        objects = values.get(keys.PERCEPTION_OBJECTS)
        if objects is not self._seen_objects and isinstance(objects, ObjectsPerception):
            self._seen_objects = objects
            for seen in objects.objects:
                self.frames.set(
                    OBJECT_PREFIX + seen.name,
                    matrix_of(seen.pose),
                    BASE,
                    now,
                    self.object_stale_after_s,
                )
        if self._joint_source is not None:
            self.set_joints(self._joint_source(now))
        else:
            joints = values.get(keys.ROBOT_JOINTS)
            if joints is not self._seen_joints and isinstance(joints, RobotJoints):
                self._seen_joints = joints
                self.set_joints(joints.positions)

    def see_face(self, user_id: str | None, face: Pose, now: datetime) -> None:
        """The face of the person in front (``user_id`` when known) is at ``face``."""
        matrix = matrix_of(face)
        self.frames.set(USER_FRAME, matrix, BASE, now, self.face_stale_after_s)
        if user_id is not None:
            self.frames.set(FACE_PREFIX + user_id, matrix, BASE, now, self.face_stale_after_s)

    def set_joints(self, positions: Mapping[str, float]) -> None:
        """The body frames follow a joint state (unnamed joints keep their position)."""
        if all(self.joints.get(name) == angle for name, angle in positions.items()):
            return
        self.joints.update(positions)
        for name, (parent, matrix) in body_frames(self.joints).items():
            self.frames.set(name, matrix, parent)


def _limit(limits: Mapping[str, float | None], key: str) -> float:
    """The input's staleness limit (not configured: the default; None: never stale)."""
    value = limits.get(key, DEFAULT_STALE_AFTER_S)
    return math.inf if value is None else value
