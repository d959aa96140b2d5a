"""Frames: where things are, relative to the robot, and how fresh that knowledge is.

The ROS Commander paper makes behaviors general by expressing motions relative to frames that
perception produces (a face, a tag), and by keeping a task frame's last known pose
when there is no live estimate. A :class:`FrameStore` keeps a small tree of frames:
``base`` (the robot's base, x forward, y left, z up) at the root, the body's frames
(``torso``, ``neck``, ``head``) set from the joint state, and named frames set from
perception (``face:<user>``, ``object:<name>``). Each perceived frame carries its time;
a lookup says whether the answer is live or last-known, and its age.

Poses are 4x4 homogeneous matrices (numpy): composing and inverting them is a few
microseconds, which keeps a lookup in a 50-frame tree under 10 µs. Rotations come from
a unit quaternion or from roll, pitch and yaw about the fixed axes (scipy's
``Rotation.from_quat`` and ``from_euler("xyz", ...)``, which a test checks them
against): the textbook formulas in numpy, so that the daemon does not need scipy.
Everything is pure and takes ``now``, like the motivation model.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from datetime import datetime, timedelta

import numpy as np
from numpy.typing import NDArray

Matrix = NDArray[np.float64]
"""A 4x4 homogeneous transform: parent <- child (a point in child -> in parent)."""

BASE = "base"
"""The root frame: the robot's base on the table, x forward, y left, z up (metres)."""

FACE_PREFIX = "face:"
OBJECT_PREFIX = "object:"


def pose(
    xyz: Sequence[float] = (0.0, 0.0, 0.0),
    quaternion: Sequence[float] | None = None,
    rpy: Sequence[float] | None = None,
) -> Matrix:
    """A transform from a translation and a rotation (quaternion x, y, z, w, or roll,
    pitch, yaw in radians); none given: no rotation."""
    matrix = np.eye(4)
    if quaternion is not None:
        matrix[:3, :3] = _from_quaternion(quaternion)
    elif rpy is not None and any(rpy):
        matrix[:3, :3] = _from_rpy(rpy)
    matrix[:3, 3] = xyz
    return matrix


def _from_quaternion(quaternion: Sequence[float]) -> Matrix:
    """The rotation matrix of quaternion (x, y, z, w), normalized first (as scipy does)."""
    x, y, z, w = (float(v) for v in quaternion)
    norm = math.sqrt(x * x + y * y + z * z + w * w)
    if not norm > 0.0 or not math.isfinite(norm):
        raise ValueError(f"not a rotation: quaternion {list(quaternion)} has no direction")
    x, y, z, w = x / norm, y / norm, z / norm, w / norm
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def _from_rpy(rpy: Sequence[float]) -> Matrix:
    """Roll about x, then pitch about y, then yaw about z, all fixed axes: Rz Ry Rx."""
    roll, pitch, yaw = (float(v) for v in rpy)
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def invert(matrix: Matrix) -> Matrix:
    """The inverse of a rigid transform (R^T, -R^T t): exact, no general inversion."""
    out = np.eye(4)
    rotation_t = matrix[:3, :3].T
    out[:3, :3] = rotation_t
    out[:3, 3] = -rotation_t @ matrix[:3, 3]
    return out


def position(matrix: Matrix) -> tuple[float, float, float]:
    x, y, z = matrix[:3, 3]
    return float(x), float(y), float(z)


@dataclass(frozen=True, slots=True)
class Located:
    """A lookup's answer: where ``target`` is in ``reference``, and how fresh that is."""

    matrix: Matrix
    live: bool
    """Every perceived frame on the way is fresher than its ``stale_after_s``."""
    age_s: float
    """The age of the oldest perceived frame on the way (0: only body frames)."""

    @property
    def position(self) -> tuple[float, float, float]:
        return position(self.matrix)


@dataclass(slots=True)
class _Frame:
    parent: str | None
    matrix: Matrix
    stamp: datetime | None
    """When perception saw it; None for a body frame (known from the joints, never stale)."""
    stale_after_s: float


class UnknownFrame(KeyError):
    """A lookup named a frame that was never set."""


class FrameStore:
    """The frames the robot knows, their parents, and their times."""

    def __init__(self, body: Mapping[str, tuple[str, Matrix]] | None = None) -> None:
        """``body``: the fixed frames (name -> (parent, transform)), e.g. a camera."""
        self._frames: dict[str, _Frame] = {BASE: _Frame(None, np.eye(4), None, math.inf)}
        self._deferred: Callable[[], None] | None = None
        self._deferred_frames: frozenset[str] = frozenset()
        self.moves = 0
        """Counts the frames set (moved) and deferred updates run: a reader that saw the
        same count before knows nothing has moved since (restamps do not count)."""
        for name, (parent, matrix) in (body or {}).items():
            self.set(name, matrix, parent=parent)

    def __contains__(self, name: str) -> bool:
        return name in self._frames

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self._frames)

    def set(
        self,
        name: str,
        matrix: Matrix,
        parent: str = BASE,
        stamp: datetime | None = None,
        stale_after_s: float = math.inf,
    ) -> None:
        """Set (or move) ``name`` relative to ``parent``; ``stamp``: when it was seen."""
        if name == BASE:
            raise ValueError("the base frame is the root: it cannot be set")
        if parent not in self._frames:
            raise UnknownFrame(parent)
        ancestor: str | None = parent
        while ancestor is not None:  # a frame may not become its own ancestor
            if ancestor == name:
                raise ValueError(f"frame {name!r} under {parent!r} would make a cycle")
            ancestor = self._frames[ancestor].parent
        self._frames[name] = _Frame(parent, matrix, stamp, stale_after_s)
        self.moves += 1

    def defer(self, frames: Iterable[str], update: Callable[[], None]) -> None:
        """Run ``update`` (which moves ``frames``) before the next lookup that goes
        through one of them, not now: a body that moves every tick is worked out only
        when someone asks where something is relative to it. The last deferred update
        replaces an earlier one."""
        self._deferred = update
        self._deferred_frames = frozenset(frames)

    def _through_deferred(self, name: str) -> bool:
        frame = self._frames.get(name)
        while frame is not None:
            if name in self._deferred_frames:
                return True
            if frame.parent is None:
                return False
            name, frame = frame.parent, self._frames.get(frame.parent)
        return False

    def live_until(self, name: str) -> datetime | None:
        """When ``name`` stops being live unless seen again (the earliest over the
        perceived frames it hangs from); None: never (only body frames on the way).

        Raises:
            UnknownFrame: ``name`` was never set.
        """
        frame = self._frames.get(name)
        if frame is None:
            raise UnknownFrame(name)
        until: datetime | None = None
        while frame.parent is not None:
            if frame.stamp is not None and math.isfinite(frame.stale_after_s):
                ends = frame.stamp + timedelta(seconds=frame.stale_after_s)
                until = ends if until is None else min(until, ends)
            frame = self._frames[frame.parent]
        return until

    def restamp(self, name: str, stamp: datetime) -> None:
        """``name`` was seen again where it was (a perception refreshed, unchanged)."""
        frame = self._frames.get(name)
        if frame is None:
            raise UnknownFrame(name)
        frame.stamp = stamp

    def forget(self, name: str) -> None:
        """Drop ``name`` and every frame under it (an object taken away)."""
        doomed = {name}
        changed = True
        while changed:
            changed = False
            for child, frame in self._frames.items():
                if frame.parent in doomed and child not in doomed:
                    doomed.add(child)
                    changed = True
        for frame_name in doomed - {BASE}:
            self._frames.pop(frame_name, None)

    def _to_base(self, name: str, now: datetime) -> tuple[Matrix, bool, float]:
        frame = self._frames.get(name)
        if frame is None:
            raise UnknownFrame(name)
        matrix, live, age = frame.matrix, True, 0.0
        while frame.parent is not None:
            if frame.stamp is not None:
                seen = (now - frame.stamp).total_seconds()
                age = max(age, seen)
                live = live and seen <= frame.stale_after_s
            parent = self._frames[frame.parent]
            if parent.parent is not None:
                matrix = parent.matrix @ matrix
            frame = parent
        return matrix, live, age

    def lookup(self, target: str, now: datetime, reference: str = BASE) -> Located:
        """Where ``target`` is in ``reference`` at ``now`` (its last known pose if stale).

        Raises:
            UnknownFrame: either frame was never set.
        """
        if self._deferred is not None and (
            self._through_deferred(target) or self._through_deferred(reference)
        ):
            update, self._deferred = self._deferred, None
            update()
            self.moves += 1
        target_in_base, live, age = self._to_base(target, now)
        if reference == BASE:
            return Located(target_in_base, live, age)
        reference_in_base, ref_live, ref_age = self._to_base(reference, now)
        return Located(
            invert(reference_in_base) @ target_in_base, live and ref_live, max(age, ref_age)
        )
