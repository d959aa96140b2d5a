"""Reachy Mini's body in the contract's terms: its axes, their limits, and the mapping.

The contract's Mini has five motors (``hip``, ``neck``, ``head``, two arms); Reachy Mini
has a turning body, a head on a Stewart platform (roll, pitch, yaw and a little height)
and two antennas. The bridge maps one onto the other:

- ``hip`` is the body's yaw;
- ``neck`` is the head's yaw relative to the body (the contract's neck pans after the
  hip, Reachy's head yaw is in the world frame), so the head's yaw is ``hip + neck``;
- ``head`` is the head's pitch (both: a positive angle, a rotation about +y, looks down);
- the arms have no counterpart: a pose keyframe's arm becomes its antenna (raised arm,
  antenna thrown out), ``robot/joints`` carries no arm.

Angles in radians, lengths in metres, x forward, y left, z up. Pure: no SDK here.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace


@dataclass(frozen=True, slots=True)
class Limit:
    """One axis's range and the top speed the bridge moves it at (rad/s or m/s)."""

    low: float
    high: float
    speed: float

    def clamp(self, value: float) -> float:
        return min(self.high, max(self.low, value))


CONTRACT: Mapping[str, Limit] = {
    "hip": Limit(-1.2, 1.2, 0.8),
    "left_arm": Limit(0.0, 2.6, 1.5),
    "right_arm": Limit(0.0, 2.6, 1.5),
    "neck": Limit(-1.0, 1.0, 1.6),
    "head": Limit(-0.45, 0.45, 1.4),
}
"""The contract's joints (docs/contract.md): what an ``aim`` or a ``pose`` names. Their
speeds are the ones the daemon times its waits on, so the bridge turns at them."""

HEAD_TILT = math.radians(40.0)
"""Reachy Mini's head pitch and roll limit (the SDK clamps to it: docs, Safety limits)."""
HEAD_YAW = math.radians(180.0)
BODY_YAW = math.radians(160.0)
YAW_DELTA = math.radians(65.0)
"""The head's yaw may differ from the body's by this much at most."""
HEAD_Z = 0.02
"""How far the head rises or sinks from rest (m): within the platform's travel."""
ANTENNA = math.radians(80.0)
"""The antennas' angle each side of upright that the gestures use (their motors turn
further; past this they would hit the head's shell in a fast gesture)."""

HEAD_ORIGIN_Z_M = 0.177
"""Height above the table of Reachy Mini's world frame (the neutral head origin, where
``look_at_world`` measures from; the SDK's ``head_z_offset`` in its kinematics and its
MuJoCo backend): the dms base frame's origin is on the table, so a position from
``perception/user`` is lowered by this before Reachy looks at it."""


@dataclass(frozen=True, slots=True)
class Posture:
    """Where every axis of the robot is, or is going: what one ``set_target`` sends.

    ``yaw`` is the head's yaw in the world frame; ``right``, ``left`` the antennas
    (0 upright)."""

    body_yaw: float = 0.0
    yaw: float = 0.0
    pitch: float = 0.0
    roll: float = 0.0
    z: float = 0.0
    right: float = 0.0
    left: float = 0.0

    def plus(self, offset: Mapping[str, float]) -> Posture:
        """This posture with each named axis moved by its offset."""
        return replace(
            self, **{axis: getattr(self, axis) + value for axis, value in offset.items()}
        )


AXES: tuple[str, ...] = ("body_yaw", "yaw", "pitch", "roll", "z", "right", "left")


def safe(posture: Posture) -> Posture:
    """The posture within Reachy Mini's limits: the body first, then the head within
    ``YAW_DELTA`` of it, the tilts and the antennas within theirs."""
    body = max(-BODY_YAW, min(BODY_YAW, posture.body_yaw))
    yaw = max(body - YAW_DELTA, min(body + YAW_DELTA, posture.yaw))
    yaw = max(-HEAD_YAW, min(HEAD_YAW, yaw))

    def within(value: float, bound: float) -> float:
        return max(-bound, min(bound, value))

    return Posture(
        body_yaw=body,
        yaw=yaw,
        pitch=within(posture.pitch, HEAD_TILT),
        roll=within(posture.roll, HEAD_TILT),
        z=within(posture.z, HEAD_Z),
        right=within(posture.right, ANTENNA),
        left=within(posture.left, ANTENNA),
    )


def arm_to_antenna(arm: float) -> float:
    """An arm's angle (0 hanging, 2.6 raised high) as how far its antenna is thrown out."""
    return ANTENNA * CONTRACT["left_arm"].clamp(arm) / CONTRACT["left_arm"].high


def from_contract(joints: Mapping[str, float], base: Posture) -> Posture:
    """``base`` with the contract joints named in ``joints`` (clamped to the contract's
    ranges) applied; joints not named keep their place, the head's yaw follows the hip."""
    hip = CONTRACT["hip"].clamp(joints["hip"]) if "hip" in joints else base.body_yaw
    neck = CONTRACT["neck"].clamp(joints["neck"]) if "neck" in joints else base.yaw - base.body_yaw
    pitch = CONTRACT["head"].clamp(joints["head"]) if "head" in joints else base.pitch
    right = -arm_to_antenna(joints["right_arm"]) if "right_arm" in joints else base.right
    left = arm_to_antenna(joints["left_arm"]) if "left_arm" in joints else base.left
    return replace(base, body_yaw=hip, yaw=hip + neck, pitch=pitch, right=right, left=left)


def to_contract(body_yaw: float, yaw: float, pitch: float) -> dict[str, float]:
    """The measured body yaw and head yaw and pitch as ``robot/joints`` positions."""
    return {
        "hip": round(body_yaw, 4),
        "neck": round(_wrap(yaw - body_yaw), 4),
        "head": round(pitch, 4),
    }


def aim_at(x: float, y: float, z: float, body_yaw: float) -> tuple[float, float]:
    """The head's world yaw and pitch that look at ``(x, y, z)``, a point in the dms base
    frame (origin on the table), from Reachy's head origin."""
    height = z - HEAD_ORIGIN_Z_M
    yaw = math.atan2(y, x)
    pitch = -math.atan2(height, math.hypot(x, y))
    return _wrap(yaw), pitch


def _wrap(angle: float) -> float:
    return math.atan2(math.sin(angle), math.cos(angle))
