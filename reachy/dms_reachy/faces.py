"""The face Reachy Mini's daemon tracks, as the daemon's ``perception/user`` (``--faces``).

Reachy Mini's daemon finds a face in its camera's image (its head tracking) and reports
where: ``x`` and ``y`` from -1 to 1 across the image, no distance. The bridge turns that
into a point in the dms base frame: the pixel's ray through the camera (its intrinsics,
lens distortion left out), from the camera's place on the head (the SDK's
head-to-camera transform) and the head's measured pose, out to :data:`FACE_DISTANCE_M`;
then up by the head origin's height (the dms base frame's origin is on the table).

:class:`Presence` says whether someone is in front: present while a face was seen in
the last :data:`LOST_S`, absent after (a glance away or a blink of the detector is not
a person leaving). Pure: numbers in, the message out, ``now`` passed in.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from dms_reachy.body import HEAD_ORIGIN_Z_M

FACE_DISTANCE_M = 0.8
"""How far the face is assumed to be: the detector gives no depth. A person seated at
the table in front of a table-top robot (the distance the dms simulated Mini's scenes
place its user at, and the middle of the range the maker's face tracking is meant for)."""
LOST_S = 1.5
"""A face not seen for this long: nobody in front."""
LIMIT_M = 100.0
"""The contract's bound on a coordinate (``perception/user`` refuses past it)."""

Matrix = Sequence[Sequence[float]]

HEAD_TO_CAMERA: tuple[tuple[float, ...], ...] = (
    (0.0, 0.0, 1.0, 0.0437),
    (-1.0, 0.0, 0.0, 0.0),
    (0.0, -1.0, 0.0, 0.0512),
    (0.0, 0.0, 0.0, 1.0),
)
"""The camera's optical frame (x right, y down, z out of the lens) in the head's frame:
the SDK's ``DEFAULT_HEAD_TO_CAMERA_TRANSFORM`` (reachy_mini/vision/look_at.py, from the
CAD)."""


@dataclass(frozen=True, slots=True)
class Intrinsics:
    """A pinhole camera: focal lengths and principal point in pixels, image size."""

    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int


LITE_CAMERA = Intrinsics(2001.808, 2003.078, 1905.876, 1328.324, 3840, 2592)
"""Reachy Mini's camera as the SDK calibrates it (``ReachyMiniLiteCamSpecs.K``, the
wireless version's too, at the full 3840x2592 image); its distortion is left out, so a
face near the image's edge is placed less well than one near its middle."""


def face_position(
    x: float,
    y: float,
    head: Matrix,
    camera: Intrinsics = LITE_CAMERA,
    distance_m: float = FACE_DISTANCE_M,
) -> tuple[float, float, float] | None:
    """Where a face at ``(x, y)`` of the image (-1..1 each) is, in the dms base frame
    (metres); ``head`` is the head's 4x4 pose in Reachy's world frame. None when the
    numbers are not a face's (outside the image, not finite)."""
    if not all(math.isfinite(v) and -1.0 <= v <= 1.0 for v in (x, y)):
        return None
    u = (x + 1.0) * 0.5 * max(camera.width - 1, 1)
    v = (y + 1.0) * 0.5 * max(camera.height - 1, 1)
    ray = ((u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy, 1.0)
    norm = math.sqrt(sum(c * c for c in ray))
    in_camera = [distance_m * c / norm for c in ray]
    in_head = _apply(HEAD_TO_CAMERA, in_camera)
    px, py, pz = _apply(head, in_head)
    point = (px, py, pz + HEAD_ORIGIN_Z_M)
    if not all(math.isfinite(c) and abs(c) <= LIMIT_M for c in point):
        return None
    return point


def _apply(matrix: Matrix, point: Sequence[float]) -> tuple[float, float, float]:
    """``matrix`` (4x4, rotation and translation) applied to a 3-D point."""
    x, y, z = (
        sum(float(matrix[row][col]) * point[col] for col in range(3)) + float(matrix[row][3])
        for row in range(3)
    )
    return x, y, z


class Presence:
    """Whether someone is in front, from the faces seen; the ``perception/user`` to send."""

    def __init__(self, lost_s: float = LOST_S) -> None:
        self.lost_s = lost_s
        self.seen: float | None = None
        self.face: tuple[float, float, float] | None = None

    def user(self, face: tuple[float, float, float] | None, now: float) -> dict[str, Any]:
        """The ``perception/user`` message at ``now``, given the face found now (None: no
        face in the image). The face's identity is unknown: ``user_id`` is None."""
        if face is not None:
            self.seen, self.face = now, face
        if self.seen is None or now - self.seen >= self.lost_s:
            self.seen = self.face = None
            return {"present": False}
        where = self.face
        assert where is not None  # set with seen
        return {
            "present": True,
            "user_id": None,
            "ready": False,
            "face": {"position": dict(zip("xyz", (round(c, 4) for c in where), strict=True))},
        }
