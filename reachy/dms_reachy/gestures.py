"""The Mini's gestures and LED patterns as Reachy Mini movements, by name.

A gesture is a timeline of keyframes: at each time (seconds from its start) an offset
per axis (:data:`dms_reachy.body.AXES`) from where the robot stands, eased from one
keyframe to the next with a cosine (no jerk at either end). Each lasts what the
simulated Mini's does, so an activity is timed the same on both; ``duration_s``
stretches it. ``sleep_pose`` and ``wake_up`` are not here: they are the SDK's own
``goto_sleep`` and ``wake_up``.

Reachy Mini has no LEDs: an ``led`` pattern is played by the antennas, as long as it
holds (until the next ``led`` command). docs/reachy.md has the table.

Pure: it returns offsets for a time; the bridge sends them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

Offsets = Mapping[str, float]
Keyframe = tuple[float, Offsets]

SDK_GESTURES = ("sleep_pose", "wake_up")
"""Gestures the SDK plays itself (``goto_sleep``, ``wake_up``)."""

_OUT = 0.6
"""Antennas thrown out (rad): the right one turns negative, the left positive."""


def _antennas(out: float, *, right: float | None = None) -> dict[str, float]:
    """Both antennas thrown out by ``out`` (the right by ``right`` if given)."""
    return {"left": out, "right": -(out if right is None else right)}


GESTURES: Mapping[str, Sequence[Keyframe]] = {
    "nod": (
        (0.35, {"pitch": 0.30}),
        (0.70, {"pitch": -0.08}),
        (1.05, {"pitch": 0.25}),
        (1.50, {}),
    ),
    "shake_head": (
        (0.35, {"yaw": 0.35}),
        (0.75, {"yaw": -0.35}),
        (1.10, {"yaw": 0.20}),
        (1.50, {}),
    ),
    "wave": (
        (0.40, {"roll": -0.12, "left": 1.0}),
        (0.80, {"roll": -0.12, "left": 0.3}),
        (1.20, {"roll": -0.12, "left": 1.0}),
        (1.60, {"roll": -0.12, "left": 0.3}),
        (2.00, {"roll": -0.12, "left": 1.0}),
        (2.50, {}),
    ),
    "bow": (
        (0.80, {"pitch": 0.45, "z": -0.01, **_antennas(0.5)}),
        (1.20, {"pitch": 0.45, "z": -0.01, **_antennas(0.5)}),
        (2.00, {}),
    ),
    "look_around": (
        (0.90, {"yaw": 0.6, "pitch": -0.1}),
        (2.10, {"yaw": -0.6, "pitch": -0.1}),
        (3.00, {}),
    ),
    "think": (
        (0.60, {"roll": 0.2, "pitch": -0.15, "yaw": 0.2, "left": -0.4}),
        (1.50, {"roll": 0.2, "pitch": -0.15, "yaw": 0.2, "left": -0.4}),
        (2.00, {}),
    ),
    "celebrate": (
        (0.30, {"z": 0.01, "pitch": -0.15, **_antennas(_OUT)}),
        (0.60, {"z": 0.01, "pitch": -0.15, **_antennas(-0.2)}),
        (0.90, {"z": 0.01, "pitch": -0.15, **_antennas(_OUT)}),
        (1.20, {"z": 0.01, "pitch": -0.15, **_antennas(-0.2)}),
        (1.50, {"z": 0.01, "pitch": -0.15, "roll": 0.15, **_antennas(_OUT)}),
        (2.00, {"z": 0.01, "pitch": -0.15, "roll": -0.15, **_antennas(-0.2)}),
        (2.50, {"z": 0.01, "pitch": -0.15, **_antennas(_OUT)}),
        (3.00, {}),
    ),
    "shrug": (
        (0.45, {"z": 0.012, "roll": 0.1, **_antennas(0.9)}),
        (1.00, {"z": 0.012, "roll": 0.1, **_antennas(0.9)}),
        (1.50, {}),
    ),
    "dance_step": (
        (0.50, {"body_yaw": 0.3, "roll": 0.2, "z": 0.008, **_antennas(0.7, right=-0.3)}),
        (1.00, {"body_yaw": 0.0, "roll": 0.0, "z": -0.004, **_antennas(0.0)}),
        (1.50, {"body_yaw": -0.3, "roll": -0.2, "z": 0.008, **_antennas(-0.3, right=0.7)}),
        (2.00, {"body_yaw": 0.0, "roll": 0.0, "z": -0.004, **_antennas(0.0)}),
        (2.50, {"body_yaw": 0.3, "roll": 0.2, "z": 0.008, **_antennas(0.7, right=-0.3)}),
        (3.00, {"body_yaw": 0.0, "roll": 0.0, "z": -0.004, **_antennas(0.0)}),
        (3.50, {"body_yaw": -0.3, "roll": -0.2, "z": 0.008, **_antennas(-0.3, right=0.7)}),
        (4.00, {}),
    ),
    "clap": (
        (0.25, _antennas(-0.5)),
        (0.50, _antennas(0.4)),
        (0.75, _antennas(-0.5)),
        (1.00, _antennas(0.4)),
        (1.25, _antennas(-0.5)),
        (1.50, _antennas(0.4)),
        (2.00, {}),
    ),
}
"""Every gesture of the Mini's repertoire but the SDK's two, as keyframes."""

SDK_GESTURE_S = {"sleep_pose": 3.5, "wake_up": 3.0}
"""About how long the SDK's ``goto_sleep`` and ``wake_up`` take (for the docs' table)."""


def known(name: str) -> bool:
    return name in GESTURES or name in SDK_GESTURES


def length(keyframes: Sequence[Keyframe]) -> float:
    return keyframes[-1][0] if keyframes else 0.0


def scaled(keyframes: Sequence[Keyframe], seconds: float | None) -> tuple[Keyframe, ...]:
    """The keyframes stretched (or shrunk) to last ``seconds`` (None: as they are)."""
    total = length(keyframes)
    if seconds is None or total <= 0.0 or seconds <= 0.0:
        return tuple(keyframes)
    factor = seconds / total
    return tuple((at * factor, offsets) for at, offsets in keyframes)


def offsets_at(keyframes: Sequence[Keyframe], elapsed: float) -> dict[str, float]:
    """Each axis's offset ``elapsed`` seconds into the timeline (from nothing at 0,
    eased between keyframes; nothing once it is over)."""
    before_at, before = 0.0, dict[str, float]()
    for at, after in keyframes:
        if elapsed < at:
            share = (elapsed - before_at) / (at - before_at) if at > before_at else 1.0
            ease = 0.5 - 0.5 * math.cos(math.pi * max(0.0, min(1.0, share)))
            axes = set(before) | set(after)
            return {
                a: before.get(a, 0.0) + (after.get(a, 0.0) - before.get(a, 0.0)) * ease
                for a in axes
            }
        before_at, before = at, dict(after)
    return {}


@dataclass(frozen=True, slots=True)
class Pattern:
    """An LED pattern played by the antennas: a swing of ``amplitude`` (rad, both
    antennas together, outward) ``hertz`` times a second around ``rest``."""

    amplitude: float
    hertz: float
    rest: float = 0.0
    times: int | None = None
    """Swings before it stops (None: as long as the pattern holds)."""

    def offsets(self, elapsed: float) -> dict[str, float]:
        cycles = elapsed * self.hertz
        if self.times is not None and cycles >= self.times:
            return _antennas(self.rest)
        swing = self.amplitude * math.sin(2.0 * math.pi * cycles)
        return _antennas(self.rest + swing)


PATTERNS: Mapping[str, Pattern] = {
    "solid": Pattern(0.0, 0.0),
    "blink": Pattern(0.35, 2.5, times=3),
    "pulse": Pattern(0.3, 1.0),
    "breathing": Pattern(0.12, 0.2),
}
"""The ``led`` channel's patterns (``solid``, ``blink``, ``pulse``, ``breathing``)."""

DIM_COLOURS = frozenset({"off", "black", "#000000"})
"""Colours that mean the lights are off: the antennas droop instead."""
DROOP = -0.5


def pattern_for(color: object, pattern: object) -> Pattern:
    """The antennas' movement for an ``led`` ``set``: its pattern (solid when unknown);
    a colour that means off droops them and holds them still."""
    if isinstance(color, str) and color.strip().lower() in DIM_COLOURS:
        return Pattern(0.0, 0.0, rest=DROOP)
    return PATTERNS.get(str(pattern), PATTERNS["solid"])
