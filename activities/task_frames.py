"""Task frames: a place defined relative to a detected marker or object, as ROS Commander's.

A behavior declares them at its top and aims at them by name (``look_at``,
``point_at``, a gesture's ``toward``)::

    frames:
      handle: {of: "object:tag7", xyz: [0.0, 0.05, 0.10]}      # metres, in the marker's frame
      shelf: {of: "object:box", xyz: [0.2, 0, 0], rpy: [0, 0, 1.57]}

A task frame is where its marker is, moved by its offset. While the marker is seen it
follows it; once the marker is lost (stale, or forgotten by the scene), the task frame
stays at its last known place (not live), so that a state with ``last_known: true`` (the
default) still aims there. Per running activity: :class:`TaskFrames` keeps the last
known places.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Mapping
from dataclasses import dataclass
from datetime import datetime
from typing import Any

from activities.names import OBJECT_NAME, frame_problem
from dms.kernel.frames import FrameStore, Located, Matrix, UnknownFrame, pose

NAME_PATTERN = OBJECT_NAME
"""A task frame's name: 1 to 64 of A-Z a-z 0-9 _ . - (no prefix: it is the behavior's own)."""
MAX_FRAMES = 32
MAX_OFFSET_M = 10.0
KEYS = ("of", "xyz", "rpy")


@dataclass(frozen=True, slots=True)
class TaskFrame:
    """``of``: the perceived frame it hangs from; ``matrix``: its place in that frame."""

    of: str
    xyz: tuple[float, float, float]
    rpy: tuple[float, float, float]

    @property
    def matrix(self) -> Matrix:
        return pose(self.xyz, rpy=self.rpy)

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"of": self.of, "xyz": list(self.xyz)}
        if any(self.rpy):
            out["rpy"] = list(self.rpy)
        return out


def parse_frames(raw: Any) -> tuple[dict[str, TaskFrame], list[tuple[str | None, str]]]:
    """The task frames of a behavior's ``frames:``, and ``(name, problem)`` for each one
    written wrong (name None: the whole mapping)."""
    if raw is None:
        return {}, []
    if not isinstance(raw, Mapping):
        return {}, [(None, "frames: a mapping of names to {of: FRAME, xyz: [x, y, z]}")]
    if len(raw) > MAX_FRAMES:
        return {}, [(None, f"frames: at most {MAX_FRAMES}")]
    frames: dict[str, TaskFrame] = {}
    problems: list[tuple[str | None, str]] = []
    for name, value in raw.items():
        name = str(name)
        problem = _problem(name, value)
        if problem is not None:
            problems.append((name, f"frames: {name}: {problem}"))
            continue
        frames[name] = TaskFrame(
            str(value["of"]), _triple(value.get("xyz")), _triple(value.get("rpy"))
        )
    return frames, problems


def _problem(name: str, value: Any) -> str | None:
    if not NAME_PATTERN.fullmatch(name) or ":" in name:
        return "a task frame's name is 1 to 64 of A-Z a-z 0-9 _ . -"
    if frame_problem(name) is None:
        return "the robot has a frame of this name already: choose another"
    if not isinstance(value, Mapping) or "of" not in value:
        return "{of: FRAME, xyz: [x, y, z], rpy: [roll, pitch, yaw]} (xyz, rpy optional)"
    unknown = sorted(str(key) for key in value if key not in KEYS)
    if unknown:
        return f"unknown key {unknown[0]!r} (keys: {', '.join(KEYS)})"
    of = value["of"]
    if not isinstance(of, str) or (problem := frame_problem(of)) is not None:
        return f"of: {problem or 'the name of a frame'}"
    for key, bound, unit in (("xyz", MAX_OFFSET_M, "metres"), ("rpy", math.pi * 2, "radians")):
        numbers = value.get(key)
        if numbers is None:
            continue
        if not (
            isinstance(numbers, list | tuple)
            and len(numbers) == 3
            and all(_finite(v) and abs(v) <= bound for v in numbers)
        ):
            return f"{key}: three numbers ({unit}, at most {bound:g} each)"
    return None


def _finite(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def _triple(value: Any) -> tuple[float, float, float]:
    if value is None:
        return (0.0, 0.0, 0.0)
    x, y, z = (float(v) for v in value)
    return (x, y, z)


def close_task_frame(frame: Any, declared: frozenset[str]) -> str | None:
    """``did you mean 'handle'?`` when ``frame`` is close to a declared task frame."""
    if not isinstance(frame, str) or not declared:
        return None
    close = difflib.get_close_matches(frame, sorted(declared), n=1, cutoff=0.6)
    return f"did you mean {close[0]!r}?" if close else None


class TaskFrames:
    """The task frames of one running activity, each with its last known place."""

    def __init__(self, frames: Mapping[str, TaskFrame]) -> None:
        self.frames = dict(frames)
        self._last: dict[str, tuple[Matrix, datetime]] = {}
        """Where each task frame was last known, and when its marker was seen there."""

    def __contains__(self, name: str) -> bool:
        return name in self.frames

    def locate(self, store: FrameStore | None, name: str, now: datetime) -> Located | None:
        """Where task frame ``name`` is now: with its marker (live while the marker is),
        else where it was last known (not live); None: its marker was never seen."""
        frame = self.frames[name]
        found: Located | None = None
        if store is not None:
            try:
                found = store.lookup(frame.of, now)
            except UnknownFrame:
                found = None
        if found is not None:
            matrix = found.matrix @ frame.matrix
            seen = now.timestamp() - found.age_s
            self._last[name] = (matrix, datetime.fromtimestamp(seen, now.tzinfo))
            return Located(matrix, found.live, found.age_s)
        kept = self._last.get(name)
        if kept is None:
            return None
        matrix, seen_at = kept
        return Located(matrix, False, max(0.0, (now - seen_at).total_seconds()))
