"""The Mini's body: its five motors' limits and speeds, and the frames they move.

The paper's Mini has a hip (turns the upper body), two arms, a neck (pans the head) and
a head (tilts it), and a 3D camera in the head that perceives the user. The frames
here are what :class:`dms.kernel.frames.FrameStore` needs to turn "the face is there,
in the base frame" into joint angles, and back: ``torso`` (after the hip), ``neck``
(after the pan), ``head`` (after the tilt, the camera's frame), and each ``shoulder``.

Angles in radians, lengths in metres; x forward, y left, z up. A positive head tilt
looks down (a rotation about +y), a positive pan or hip turn looks left.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from dms.kernel.frames import BASE, Matrix, pose

TORSO, NECK, HEAD = "torso", "neck", "head"
LEFT_SHOULDER, RIGHT_SHOULDER = "shoulder:left", "shoulder:right"

HIP_HEIGHT_M = 0.10
NECK_HEIGHT_M = 0.30
"""Above the hip: where the neck pans."""
HEAD_HEIGHT_M = 0.05
"""Above the neck: where the head tilts (the camera is in front of it)."""
CAMERA_FORWARD_M = 0.06
SHOULDER_HEIGHT_M = 0.24
SHOULDER_SIDE_M = 0.10


@dataclass(frozen=True, slots=True)
class Joint:
    """One motor: its range and its top speed."""

    low: float
    high: float
    speed: float
    """rad/s."""
    neutral: float = 0.0

    def clamp(self, angle: float) -> float:
        return min(self.high, max(self.low, angle))


JOINTS: Mapping[str, Joint] = {
    "hip": Joint(-1.2, 1.2, 0.8),
    "left_arm": Joint(0.0, 2.6, 1.5),
    "right_arm": Joint(0.0, 2.6, 1.5),
    "neck": Joint(-1.0, 1.0, 1.6),
    "head": Joint(-0.45, 0.45, 1.4),
}
"""The Mini's five motors; an arm at 0 hangs down, at pi/2 points forward."""

NEUTRAL: Mapping[str, float] = {name: joint.neutral for name, joint in JOINTS.items()}


def body_frames(joints: Mapping[str, float]) -> dict[str, tuple[str, Matrix]]:
    """The body's frames for a joint state (missing joints at neutral), parent first."""
    angle = {**NEUTRAL, **joints}
    return {
        TORSO: (BASE, pose((0.0, 0.0, HIP_HEIGHT_M), rpy=(0.0, 0.0, angle["hip"]))),
        NECK: (TORSO, pose((0.0, 0.0, NECK_HEIGHT_M), rpy=(0.0, 0.0, angle["neck"]))),
        HEAD: (
            NECK,
            pose((CAMERA_FORWARD_M, 0.0, HEAD_HEIGHT_M), rpy=(0.0, angle["head"], 0.0)),
        ),
        LEFT_SHOULDER: (
            TORSO,
            pose((0.0, SHOULDER_SIDE_M, SHOULDER_HEIGHT_M), rpy=(0.0, -angle["left_arm"], 0.0)),
        ),
        RIGHT_SHOULDER: (
            TORSO,
            pose((0.0, -SHOULDER_SIDE_M, SHOULDER_HEIGHT_M), rpy=(0.0, -angle["right_arm"], 0.0)),
        ),
    }
