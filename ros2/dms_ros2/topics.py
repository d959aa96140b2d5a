"""What the bridge carries: each dms key, its ROS 2 topic, type and QoS, in one table.

The keys and their JSON are dms's public contract (docs/contract.md); this module
names them again rather than importing dms, because the bridge lives in an environment
of its own. ROS 2 topic names are relative to the node's namespace
``/robots/<robot_id>``, except ``/diagnostics``, which rqt_robot_monitor reads.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from enum import Enum

ROBOT_ID_RE = re.compile(r"[a-z0-9_-]+")
"""The contract's robot ids, matched whole (``fullmatch``: ``$`` lets a line break end one)."""


class Direction(Enum):
    """Which way a row carries messages."""

    OUT = "dms -> ROS 2"
    """Zenoh key to ROS 2 topic."""
    IN = "ROS 2 -> dms"
    """ROS 2 topic to Zenoh key."""


class Qos(Enum):
    """The QoS a row's ROS 2 endpoint is made with (docs/ros2.md has the table)."""

    EVENTS = "reliable, volatile, keep last 50"
    """Every message counts: decisions, commands, requests."""
    LATCHED = "reliable, transient local, keep last 1"
    """The latest value is what counts, and a late subscriber gets it at once."""
    SENSOR = "best effort, volatile, keep last 10"
    """A stream where the newest sample matters; matches reliable and best-effort peers."""
    DIAGNOSTICS = "reliable, volatile, keep last 10"
    """What /diagnostics publishers use."""


@dataclass(frozen=True, slots=True)
class Route:
    """One bridged key: its Zenoh key (after ``robots/<id>/``), ROS 2 topic and type."""

    key: str
    topic: str
    ros_type: str
    direction: Direction
    qos: Qos
    note: str = ""


STRING = "std_msgs/msg/String"

OUT_ROUTES = (
    Route("dms/decision", "dms/decision", STRING, Direction.OUT, Qos.EVENTS, "same JSON"),
    Route("dms/state", "dms/state", STRING, Direction.OUT, Qos.LATCHED, "same JSON"),
    Route("dms/errors", "dms/errors", STRING, Direction.OUT, Qos.EVENTS, "same JSON"),
    Route("robot/command", "robot/command", STRING, Direction.OUT, Qos.EVENTS, "same JSON"),
    Route(
        "robot/joints",
        "joint_states",
        "sensor_msgs/msg/JointState",
        Direction.OUT,
        Qos.EVENTS,
        "names and radians",
    ),
    Route(
        "perception/user, perception/objects, robot/command (aim)",
        "dms/frames",
        "visualization_msgs/msg/MarkerArray",
        Direction.OUT,
        Qos.LATCHED,
        "the person, faces, objects, where the robot looks",
    ),
    Route(
        "dms/state",
        "/diagnostics",
        "diagnostic_msgs/msg/DiagnosticArray",
        Direction.OUT,
        Qos.DIAGNOSTICS,
        "1 Hz: the daemon, each input, the robot link, storage",
    ),
)

STRING_INPUTS = (
    "request",
    "perception/user",
    "perception/touch",
    "perception/speech",
    "perception/screen",
    "perception/objects",
    "params/robot",
    "params/env",
    "robot/feedback",
)
"""Inputs carried as ``std_msgs/String`` holding the contract's JSON, unchanged."""

FACE_TOPIC = "perception/face"
FACE_KEY = "perception/user"

IN_ROUTES = (
    *(Route(key, key, STRING, Direction.IN, Qos.EVENTS, "same JSON") for key in STRING_INPUTS),
    Route(
        FACE_KEY,
        FACE_TOPIC,
        "geometry_msgs/msg/PoseStamped",
        Direction.IN,
        Qos.SENSOR,
        "merged into perception/user as its face",
    ),
)

ROUTES = OUT_ROUTES + IN_ROUTES


def ros_namespace(robot_id: str) -> str:
    """``/robots/<robot_id>``, the id made a valid ROS 2 name token: ``-`` becomes ``_``
    and a leading digit gets a ``_`` before it (ROS 2 names allow neither)."""
    token = robot_id.replace("-", "_")
    if token[:1].isdigit():
        token = "_" + token
    return f"/robots/{token}"


def json_object_error(text: str) -> str | None:
    """Why ``text`` is not a JSON object, or None when it is one. The daemon validates
    the fields; the bridge only says early, in the ROS log, what the daemon will reject."""
    try:
        value = json.loads(text)
    except ValueError as error:
        return f"not JSON: {error}"
    if not isinstance(value, dict):
        return f"not a JSON object but {type(value).__name__}"
    return None


def table(robot_id: str) -> list[str]:
    """The lines the bridge logs at start: what it carries, each way, with full names."""
    namespace = ros_namespace(robot_id)
    lines = []
    for route in ROUTES:
        topic = route.topic if route.topic.startswith("/") else f"{namespace}/{route.topic}"
        keys = ", ".join(f"robots/{robot_id}/{k}" for k in route.key.split(", "))
        if route.direction is Direction.OUT:
            lines.append(f"{keys} -> {topic} [{route.ros_type}; {route.qos.value}]")
        else:
            lines.append(f"{topic} [{route.ros_type}; {route.qos.value}] -> {keys}")
    return lines
