"""The contract's JSON turned into ROS 2 messages, and back (a face into perception/user).

Pure: each function takes the JSON (and ``now`` where age matters) and returns a
message; the node in :mod:`dms_ros2.bridge` does the I/O. Positions are in the robot's
base frame (x forward, y left, z up, metres), as the contract gives them.
"""

from __future__ import annotations

from datetime import datetime
from typing import Any

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Point, PoseStamped
from sensor_msgs.msg import JointState
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

Json = dict[str, Any]

STATE_STALE_S = 3.0
"""``dms/state`` comes twice a second: older than this, the daemon is not heard."""
FACE_LIVE_S = 2.0
"""A face or object not seen again for this long is drawn as last known (the daemon's
``[frames] face_live_s`` default)."""
MAX_NAMED = 256
"""Faces and objects remembered; past it the one seen longest ago is forgotten."""
HEAD = Point(x=0.06, y=0.0, z=0.45)
"""Where the robot's camera is at rest, for the arrow of where it looks."""

INPUT_LEVELS = {
    "ok": DiagnosticStatus.OK,
    "not_published": DiagnosticStatus.OK,
    "stale": DiagnosticStatus.WARN,
}
"""An input's status in ``dms/state`` as a diagnostic level; anything else is an error
(``not_published``: parameters nobody ever sent, as on most robots, are no fault)."""


def stamp_of(seconds: float) -> Time:
    whole = int(seconds)
    return Time(sec=whole, nanosec=int((seconds - whole) * 1e9))


def seconds_of(iso_time: object) -> float | None:
    """The contract's ISO-8601 UTC time as epoch seconds, or None when it is not one."""
    if not isinstance(iso_time, str):
        return None
    try:
        return datetime.fromisoformat(iso_time.replace("Z", "+00:00")).timestamp()
    except ValueError:
        return None


def _status(level: bytes, name: str, message: str, robot_id: str, **values: object) -> Any:
    return DiagnosticStatus(
        level=level,
        name=name,
        message=message,
        hardware_id=robot_id,
        values=[KeyValue(key=key, value=str(value)) for key, value in values.items()],
    )


def diagnostics(
    robot_id: str, state: Json | None, state_age_s: float | None, alive: bool, now: float
) -> DiagnosticArray:
    """The daemon's health for rqt_robot_monitor: the daemon itself, then one status per
    input (OK, WARN stale, ERROR missing), the robot link and storage, from the latest
    ``dms/state`` (``state_age_s`` old) and whether ``alive/dms`` is declared."""
    prefix = f"dms {robot_id}"
    array = DiagnosticArray()
    array.header.stamp = stamp_of(now)
    if state is None or state_age_s is None:
        why = "alive/dms declared, no dms/state yet" if alive else "no daemon on the bus"
        array.status = [_status(DiagnosticStatus.ERROR, f"{prefix}: daemon", why, robot_id)]
        return array
    fresh = state_age_s <= STATE_STALE_S
    if fresh and alive:
        level, message = DiagnosticStatus.OK, "running"
    elif alive:
        level, message = DiagnosticStatus.WARN, f"no dms/state for {state_age_s:.0f} s"
    else:
        level, message = DiagnosticStatus.ERROR, "alive/dms not declared"
    activity = state.get("activity") or {}
    statuses = [
        _status(
            level,
            f"{prefix}: daemon",
            message,
            robot_id,
            tick=state.get("tick"),
            mode=state.get("mode"),
            activity=activity.get("name") if isinstance(activity, dict) else None,
            state_age_s=round(state_age_s, 1),
        )
    ]
    inputs = state.get("inputs")
    for key, health in (inputs if isinstance(inputs, dict) else {}).items():
        statuses.append(
            _status(
                INPUT_LEVELS.get(str(health), DiagnosticStatus.ERROR),
                f"{prefix}: input {key}",
                str(health),
                robot_id,
            )
        )
    link = state.get("robot_link", "ok")
    statuses.append(
        _status(
            DiagnosticStatus.OK if link == "ok" else DiagnosticStatus.ERROR,
            f"{prefix}: robot link",
            str(link),
            robot_id,
        )
    )
    storage = state.get("storage", "ok")
    statuses.append(
        _status(
            DiagnosticStatus.OK if storage == "ok" else DiagnosticStatus.WARN,
            f"{prefix}: storage",
            str(storage),
            robot_id,
            pending_writes=state.get("pending_writes", 0),
        )
    )
    array.status = statuses
    return array


def joint_state(joints: Json, now: float) -> JointState | None:
    """``robot/joints`` as a JointState (names sorted), stamped with its ``time`` when it
    has one; None when it holds no positions."""
    positions = joints.get("positions")
    if not isinstance(positions, dict) or not positions:
        return None
    names = sorted(str(name) for name in positions)
    message = JointState()
    message.header.stamp = stamp_of(seconds_of(joints.get("time")) or now)
    message.name = names
    message.position = [float(positions[name]) for name in names]
    return message


def face_into_user(user: Json | None, face: PoseStamped) -> Json:
    """The latest ``perception/user`` with ``face`` set to the pose (someone present,
    nobody known, when no perception/user came before)."""
    merged: Json = dict(user) if user else {"present": True, "user_id": None, "ready": False}
    p, q = face.pose.position, face.pose.orientation
    orientation = None if (q.x, q.y, q.z, q.w) == (0.0, 0.0, 0.0, 0.0) else q
    merged["face"] = {
        "position": {"x": p.x, "y": p.y, "z": p.z},
        "orientation": None if orientation is None else {"x": q.x, "y": q.y, "z": q.z, "w": q.w},
    }
    return merged


def _point(where: object) -> Point | None:
    """A contract position ``{"x", "y", "z"}`` (or a Pose's), or None when it is not one."""
    if isinstance(where, dict) and isinstance(where.get("position"), dict):
        where = where["position"]
    if not isinstance(where, dict):
        return None
    try:
        return Point(x=float(where["x"]), y=float(where["y"]), z=float(where["z"]))
    except (KeyError, TypeError, ValueError):
        return None


class Frames:
    """What the markers show, kept from the keys the daemon makes its frames of: the
    person in front (``perception/user``'s face), each user's face, the objects
    (``perception/objects``) and where the robot looks or points (``robot/command``'s
    ``aim`` channel). Poses are kept last known, like the daemon's frames."""

    def __init__(self, frame_id: str) -> None:
        self.frame_id = frame_id
        self.user: tuple[Point, str, float] | None = None
        self.faces: dict[str, tuple[Point, float]] = {}
        self.objects: dict[str, tuple[Point, float]] = {}
        self.aim: tuple[Point, str] | None = None
        self._ids: dict[str, int] = {}

    def on_user(self, user: Json, now: float) -> None:
        face = _point(user.get("face"))
        if not user.get("present"):
            self.user = None
        elif face is not None:
            user_id = user.get("user_id")
            self.user = (face, str(user_id) if user_id else "someone", now)
            if user_id:
                self._remember(self.faces, f"face:{user_id}", face, now)

    def on_objects(self, objects: Json, now: float) -> None:
        for item in objects.get("objects") or ():
            where = _point(item.get("pose")) if isinstance(item, dict) else None
            if where is not None:
                self._remember(self.objects, f"object:{item.get('name')}", where, now)

    def on_command(self, command: Json) -> None:
        if command.get("channel") != "aim":
            return
        args = command.get("args") or {}
        target = _point(args.get("position")) if isinstance(args, dict) else None
        if target is None or args.get("frame") is None:
            self.aim = None
        else:
            self.aim = (target, f"{command.get('action')} {args.get('frame')}")

    def _remember(
        self, table: dict[str, tuple[Point, float]], name: str, where: Point, now: float
    ) -> None:
        table.pop(name, None)
        table[name] = (where, now)
        if len(table) > MAX_NAMED:
            del table[next(iter(table))]

    def _id(self, name: str) -> int:
        if name not in self._ids:
            if len(self._ids) >= 4 * MAX_NAMED:
                self._ids.clear()  # ids are reused only after a DELETEALL, below
            self._ids[name] = len(self._ids)
        return self._ids[name]

    def markers(self, now: float) -> MarkerArray:
        """Every marker, after a DELETEALL so that forgotten ones disappear."""
        out = [Marker(action=Marker.DELETEALL)]
        if self.user is not None:
            where, who, seen = self.user
            live = now - seen <= FACE_LIVE_S
            out.append(self._marker("person", 0, Marker.SPHERE, where, 0.18, live))
            out.append(self._label("person", 1, where, who, now - seen))
        for name, (where, seen) in self.faces.items():
            live = now - seen <= FACE_LIVE_S
            out.append(self._marker("faces", self._id(name), Marker.SPHERE, where, 0.08, live))
            out.append(self._label("face_labels", self._id(name), where, name, now - seen))
        for name, (where, seen) in self.objects.items():
            live = now - seen <= FACE_LIVE_S
            out.append(self._marker("objects", self._id(name), Marker.CUBE, where, 0.06, live))
            out.append(self._label("object_labels", self._id(name), where, name, now - seen))
        if self.aim is not None:
            target, what = self.aim
            arrow = self._marker("look", 0, Marker.ARROW, None, 0.02, True)
            arrow.points = [HEAD, target]
            arrow.scale.y = 0.04
            arrow.scale.z = 0.06
            out.append(arrow)
            out.append(self._label("look", 1, target, what, 0.0))
        for marker in out:
            marker.header.frame_id = self.frame_id
            marker.header.stamp = stamp_of(now)
        return MarkerArray(markers=out)

    def _marker(
        self, ns: str, id_: int, kind: int, where: Point | None, size: float, live: bool
    ) -> Marker:
        marker = Marker(ns=ns, id=id_, type=kind, action=Marker.ADD)
        if where is not None:
            marker.pose.position = where
        marker.pose.orientation.w = 1.0
        marker.scale.x = marker.scale.y = marker.scale.z = size
        marker.color = (
            ColorRGBA(r=0.2, g=0.8, b=0.3, a=0.9) if live else ColorRGBA(r=0.6, g=0.6, b=0.6, a=0.6)
        )
        return marker

    def _label(self, ns: str, id_: int, where: Point, text: str, age_s: float) -> Marker:
        marker = Marker(ns=ns, id=id_, type=Marker.TEXT_VIEW_FACING, action=Marker.ADD)
        marker.pose.position = Point(x=where.x, y=where.y, z=where.z + 0.12)
        marker.pose.orientation.w = 1.0
        marker.scale.z = 0.05
        marker.color = ColorRGBA(r=1.0, g=1.0, b=1.0, a=1.0)
        marker.text = text if age_s <= FACE_LIVE_S else f"{text} ({age_s:.0f} s ago)"
        return marker
