"""The contract's ``robot/command`` read from its JSON, and the keys the bridge uses.

A command from the bus is checked here before the robot sees it: a payload that is not
a JSON object, too long, or without a usable ``id``, ``channel`` and ``action`` is
dropped with one line saying why (the daemon never publishes one; another program on
the bus might). Pure.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass, field
from typing import Any

ROBOT_ID_RE = re.compile(r"^[a-z0-9_-]+$")
MAX_PAYLOAD = 64 * 1024
"""The longest command read (a speech of 4,096 characters is far shorter)."""
MAX_ID = 128

CHANNELS = frozenset({"speech", "screen", "led", "motion", "media", "aim"})


class BadCommand(ValueError):
    """A ``robot/command`` the bridge cannot read; the message says what was wrong."""


@dataclass(frozen=True, slots=True)
class Command:
    id: str
    channel: str
    action: str
    args: dict[str, Any] = field(default_factory=dict)


def parse(raw: bytes) -> Command:
    """The command in ``raw``; raises BadCommand naming the problem."""
    if len(raw) > MAX_PAYLOAD:
        raise BadCommand(f"{len(raw)} bytes, more than {MAX_PAYLOAD}")
    try:
        data = json.loads(raw)
    except (ValueError, UnicodeDecodeError) as error:
        raise BadCommand(f"not JSON ({error})") from None
    if not isinstance(data, dict):
        raise BadCommand("not a JSON object")
    command_id, channel, action = data.get("id"), data.get("channel"), data.get("action")
    if not isinstance(command_id, str) or not 0 < len(command_id) <= MAX_ID:
        raise BadCommand("id must be a string of 1 to 128 characters")
    if channel not in CHANNELS:
        raise BadCommand(f"channel {channel!r} is not one of {sorted(CHANNELS)}")
    if not isinstance(action, str) or not action:
        raise BadCommand("action must be a string")
    args = data.get("args", {})
    if not isinstance(args, dict):
        raise BadCommand("args must be an object")
    return Command(command_id, str(channel), action, args)


def joints_of(args: dict[str, Any]) -> dict[str, float]:
    """The finite numbers of ``args.joints`` by joint name (anything else left out)."""
    joints = args.get("joints")
    if not isinstance(joints, dict):
        return {}
    return {
        str(name): float(angle)
        for name, angle in joints.items()
        if isinstance(angle, int | float) and not isinstance(angle, bool) and math.isfinite(angle)
    }


def position_of(args: dict[str, Any]) -> tuple[float, float, float] | None:
    """``args.position`` as (x, y, z) metres, or None when absent or not three numbers
    within 100 m (the contract's bound)."""
    position = args.get("position")
    if not isinstance(position, dict):
        return None
    values = [position.get(axis) for axis in ("x", "y", "z")]
    if not all(
        isinstance(v, int | float)
        and not isinstance(v, bool)
        and math.isfinite(v)
        and abs(v) <= 100
        for v in values
    ):
        return None
    x, y, z = (float(v) for v in values)  # type: ignore[arg-type]
    return x, y, z


def seconds_of(value: object, default: float, longest: float) -> float:
    """A duration from a command's args: a number 0..``longest``, else ``default``."""
    if isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value):
        return max(0.0, min(longest, float(value)))
    return default


def feedback(command_id: str, status: str, detail: str | None = None) -> bytes:
    """A ``robot/feedback`` payload."""
    return json.dumps({"id": command_id, "status": status, "detail": detail}).encode()
