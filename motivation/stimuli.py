"""From perception to stimuli: what excites or calms each drive right now.

The controller fills a ``Percepts`` from the inputs that are ok each tick (a stale or
missing input is ``None`` and contributes nothing) and the model turns it into a
``Stimuli``: a level in [0, 1] per drive (``w_i``), a continuous relief in points per
second (a user engaged calms loneliness) and an instant relief (each caress).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from motivation.config import STIMULUS_SOURCES, StimulusConfig, StimulusSource
from motivation.dynamics import FloatArray


@dataclass(frozen=True)
class Percepts:
    """What the robot perceives this tick; ``None`` means not known (stale or missing)."""

    user_present: bool | None = None
    engagement: float | None = None
    env: Mapping[str, Any] | None = None
    touches: tuple[tuple[str, str], ...] = ()
    """(part, kind) of each touch since the last tick."""


@dataclass(frozen=True)
class Stimuli:
    """Per drive: ``levels`` w_i in [0, 1], ``relief`` points/s, ``instant`` points off now."""

    levels: FloatArray
    relief: FloatArray
    instant: FloatArray = field(default_factory=lambda: np.zeros(0))

    def __post_init__(self) -> None:
        if self.instant.size == 0:
            object.__setattr__(self, "instant", np.zeros_like(self.levels))

    def without_instant(self) -> Stimuli:
        """The same stimuli once the instant relief has been applied."""
        return Stimuli(self.levels, self.relief, np.zeros_like(self.levels))


def _number(env: Mapping[str, Any], name: str) -> float | None:
    value = env.get(name)
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        return None
    return float(value)


def _clamp(value: float) -> float:
    return min(1.0, max(0.0, value))


def source_levels(percepts: Percepts, config: StimulusConfig) -> dict[StimulusSource, float]:
    """Each stimulus source in [0, 1]; unknown inputs give 0."""
    levels: dict[StimulusSource, float] = dict.fromkeys(STIMULUS_SOURCES, 0.0)
    if percepts.user_present:
        engagement = percepts.engagement
        levels["user"] = _clamp(config.default_engagement if engagement is None else engagement)
    env = percepts.env or {}
    lux = _number(env, "light_lux")
    if lux is not None:
        levels["darkness"] = _clamp(1.0 - lux / config.dark_lux)
    noise = _number(env, "noise_db")
    if noise is not None:
        levels["quiet"] = _clamp((config.loud_db - noise) / (config.loud_db - config.quiet_db))
    music = env.get("music")
    if music is True or (_number(env, "music") or 0.0) > 0:
        levels["music"] = 1.0
    if any(kind == "caress" for _part, kind in percepts.touches):
        levels["caress"] = 1.0
    return levels


def caress_count(percepts: Percepts) -> int:
    """How many caresses this tick brought."""
    return sum(1 for _part, kind in percepts.touches if kind == "caress")
