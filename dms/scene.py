"""The scene: the robot's frames, kept current from what it perceives and its joints.

Each tick the controller hands :meth:`Scene.update` the inputs that are ok. A new
``perception/user`` with a ``face`` moves the frames ``user`` (whoever is in front)
and ``face:<user_id>``; a new ``perception/objects`` moves ``object:<name>`` for each
object seen. A frame is *live* while it is seen again within ``[frames] face_live_s``
(``object_live_s``) and *last known* after, with its age: behaviors choose what to do
with an old pose (the task frames of "ROS Commander"). The body's frames follow the joint state:
the simulated Mini's own, or the external robot's ``robot/joints``.

Pure and on the caller's clock, like the motivation model: nothing here reads time.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from collections.abc import Set as AbstractSet
from datetime import datetime

from pydantic import BaseModel

from dms.kernel import keys
from dms.kernel.body import NEUTRAL, body_frames
from dms.kernel.frames import BASE, FACE_PREFIX, OBJECT_PREFIX, FrameStore, Matrix, pose
from dms.kernel.messages import ObjectsPerception, Pose, RobotJoints, UserPerception

USER_FRAME = "user"
"""The face of whoever is in front of the robot: what ``attend`` and ``look_at`` follow
by default."""

DEFAULT_LIVE_S = 2.0
MAX_PERCEIVED = 256
"""Named frames kept (faces, objects): past it the one seen longest ago is forgotten, so
a detector that invents a new name a frame cannot grow a months-long daemon."""
BODY_FRAMES = tuple(body_frames(NEUTRAL))
"""The frames the joints move (``torso``, ``neck``, ``head``, the shoulders)."""

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
        face_live_s: float = DEFAULT_LIVE_S,
        object_live_s: float = DEFAULT_LIVE_S,
        joints: JointSource | None = None,
    ) -> None:
        """``face_live_s``, ``object_live_s``: how long a frame not seen again is live
        (``[frames]``); ``joints``: the in-process robot's joint state, if it has one."""
        self.face_live_s = face_live_s
        self.object_live_s = object_live_s
        self.frames = FrameStore(body_frames(NEUTRAL))
        self.joints: dict[str, float] = dict(NEUTRAL)
        """The joint state the body frames were last set from."""
        self._joint_source = joints
        self._face: Pose | None = None
        self._face_name: str | None = None
        """The face last set (a refresh of the same message only restamps it)."""
        self._named: dict[str, None] = {}
        """The faces and objects set, least recently seen first (for :data:`MAX_PERCEIVED`)."""

    def update(
        self, values: Mapping[str, BaseModel], fresh: AbstractSet[str], now: datetime
    ) -> None:
        """Move the frames from this tick's inputs: ``values`` those that are ok,
        ``fresh`` the keys received since the last tick (a refresh renews a frame)."""
        if keys.PERCEPTION_USER in fresh:
            user = values.get(keys.PERCEPTION_USER)
            if isinstance(user, UserPerception) and user.present and user.face is not None:
                self.see_face(user.user_id, user.face, now)
        if keys.PERCEPTION_OBJECTS in fresh:
            objects = values.get(keys.PERCEPTION_OBJECTS)
            if isinstance(objects, ObjectsPerception):
                for seen in objects.objects:
                    self._set_named(
                        OBJECT_PREFIX + seen.name, matrix_of(seen.pose), now, self.object_live_s
                    )
        if self._joint_source is not None:
            self.set_joints(self._joint_source(now))
        elif keys.ROBOT_JOINTS in fresh:
            joints = values.get(keys.ROBOT_JOINTS)
            if isinstance(joints, RobotJoints):
                self.set_joints(joints.positions)

    def see_face(self, user_id: str | None, face: Pose, now: datetime) -> None:
        """The face of the person in front (``user_id`` when known) is at ``face``."""
        named = None if user_id is None else FACE_PREFIX + user_id
        if face is self._face and named == self._face_name:  # refreshed, unchanged: cheap
            self.frames.restamp(USER_FRAME, now)
            if named is not None:
                self.frames.restamp(named, now)
                self._named.pop(named, None)  # seen now: the last to be forgotten
                self._named[named] = None
            return
        self._face, self._face_name = face, named
        matrix = matrix_of(face)
        self.frames.set(USER_FRAME, matrix, BASE, now, self.face_live_s)
        if named is not None:
            self._set_named(named, matrix, now, self.face_live_s)

    def _set_named(self, name: str, matrix: Matrix, now: datetime, live_s: float) -> None:
        """Set a perceived frame; forget the one seen longest ago past :data:`MAX_PERCEIVED`."""
        self.frames.set(name, matrix, BASE, now, live_s)
        self._named.pop(name, None)
        self._named[name] = None
        if len(self._named) > MAX_PERCEIVED:
            oldest = next(iter(self._named))
            del self._named[oldest]
            self.frames.forget(oldest)

    def set_joints(self, positions: Mapping[str, float]) -> None:
        """The body frames follow a joint state (unnamed joints keep their position)."""
        if positions == self.joints or all(
            self.joints.get(name) == angle for name, angle in positions.items()
        ):
            return  # the common case, a body at rest, costs one dict comparison
        self.joints.update(positions)
        self.frames.defer(BODY_FRAMES, self._move_body)

    def _move_body(self) -> None:
        """The body frames at the joints' last positions (deferred to the next lookup:
        gaze and pointing work in the base frame and need none of them)."""
        for name, (parent, matrix) in body_frames(self.joints).items():
            self.frames.set(name, matrix, parent)
