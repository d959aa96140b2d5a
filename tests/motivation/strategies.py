"""Hypothesis strategies for the motivation model: configurations, states, inputs, clocks.

Random configurations use large rates (up to 100 points an hour, satisfied at up to
100 points a minute) so that a short run crosses thresholds, hits the walls at 0 and
100 and switches the dominant drive: the interesting events happen within minutes.
"""

from __future__ import annotations

from datetime import UTC, datetime, timedelta
from typing import Any
from zoneinfo import ZoneInfo

import numpy as np
from hypothesis import strategies as st

from dms.kernel.activity_names import ACTIVITIES
from motivation import MotivationModel, MotivationState, Stimuli, load_config
from motivation.config import STIMULUS_SOURCES
from motivation.model import NO_DOMINANT

BEHAVIORS = tuple(ACTIVITIES)
ZONES = ("UTC", "Europe/Madrid", "America/New_York", "Australia/Lord_Howe", "Asia/Kolkata")
TRANSITIONS = (
    datetime(2026, 3, 29, 1, 0, tzinfo=UTC),  # Madrid: +1 -> +2
    datetime(2026, 10, 25, 1, 0, tzinfo=UTC),  # Madrid: +2 -> +1
    datetime(2026, 3, 8, 7, 0, tzinfo=UTC),  # New York: -5 -> -4
    datetime(2026, 10, 3, 15, 30, tzinfo=UTC),  # Lord Howe: +10:30 -> +11 (half an hour)
)
"""Daylight-saving changes in 2026 of the zones above, as UTC instants."""

levels01 = st.floats(0.0, 1.0)
per_minute = st.floats(0.0, 100.0)


@st.composite
def drive_specs(draw: st.DrawFn) -> dict[str, Any]:
    """One drive's table, every field in its range."""
    threshold = draw(st.floats(0.0, 100.0))
    spec: dict[str, Any] = {
        "rate_per_hour": draw(st.floats(0.0, 100.0)),
        "amplitude": draw(levels01),
        "peak_hour": draw(st.floats(0.0, 23.99)),
        "threshold": threshold,
        "stimulus_weight": draw(st.floats(0.0, 100.0)),
        "wellbeing_weight": draw(st.floats(0.0, 100.0)),
        "stimuli": draw(st.lists(st.sampled_from(STIMULUS_SOURCES), max_size=3, unique=True)),
        "relieved_by": draw(
            st.dictionaries(st.sampled_from(STIMULUS_SOURCES), per_minute, max_size=2)
        ),
        "touch_relief": draw(st.floats(0.0, 100.0)),
        "behavior": draw(st.sampled_from(BEHAVIORS)),
        "satisfied_by": draw(st.dictionaries(st.sampled_from(BEHAVIORS), per_minute, max_size=3)),
        "dormant_during": draw(st.lists(st.sampled_from(BEHAVIORS), max_size=2, unique=True)),
        "initial": draw(st.floats(0.0, 100.0)),
    }
    if draw(st.booleans()):
        spec["satiation"] = draw(st.floats(0.0, threshold))
    return spec


@st.composite
def configs(draw: st.DrawFn, still: bool = False) -> dict[str, Any]:
    """A ``[motivation]`` table: the shipped drives, or one to four random ones.

    ``still``: no drive grows (rate 0), for tests where only the stimuli move.
    """
    if draw(st.booleans()):
        drives: dict[str, Any] = {name: {} for name in ("rest", "social", "play")}
    else:
        count = draw(st.integers(1, 4))
        drives = {f"d{i}": draw(drive_specs()) for i in range(count)}
        drives.update({name: {"enabled": False} for name in ("rest", "social", "play")})
    if still:
        for spec in drives.values():
            spec["rate_per_hour"] = 0.0
    return {
        "drives": drives,
        "hysteresis": draw(st.floats(0.0, 100.0)),
        "idle_behavior": draw(st.sampled_from(BEHAVIORS)),
    }


@st.composite
def models(draw: st.DrawFn, still: bool = False) -> MotivationModel:
    """A model for a random configuration in a random time zone."""
    config = load_config(draw(configs(still)))
    return MotivationModel(config, ZoneInfo(draw(st.sampled_from(ZONES))))


def states(model: MotivationModel) -> st.SearchStrategy[MotivationState]:
    """Any drives in [0, 100], any stimulus levels, any dominant drive the rule allows."""
    n = len(model.names)

    def build(drives: list[float], levels: list[float], previous: int) -> MotivationState:
        d, w = np.array(drives), np.array(levels)
        return MotivationState(d, w, model.next_dominant(previous, d, w))

    return st.builds(
        build,
        st.lists(st.floats(0.0, 100.0), min_size=n, max_size=n),
        st.lists(levels01, min_size=n, max_size=n),
        st.integers(NO_DOMINANT, n - 1),
    )


def stimuli(model: MotivationModel, instant: bool = True) -> st.SearchStrategy[Stimuli]:
    """Any levels in [0, 1], relief up to 3 points a minute, caresses up to 10 points."""
    n = len(model.names)

    def vector(low: float, high: float) -> st.SearchStrategy[Any]:
        return st.lists(st.floats(low, high), min_size=n, max_size=n).map(np.array)

    return st.builds(
        Stimuli,
        vector(0.0, 1.0),
        vector(0.0, 0.05),
        vector(0.0, 10.0) if instant else st.just(np.zeros(n)),
    )


def runnings(model: MotivationModel) -> st.SearchStrategy[str | None]:
    """Nothing, a behavior the model knows, or any other activity."""
    drives = model.config.active_drives.values()
    known = sorted({*model.table.behaviors, *(b for d in drives for b in d.satisfied_by)})
    return st.one_of(st.none(), st.sampled_from(known), st.sampled_from(BEHAVIORS))


def instants() -> st.SearchStrategy[datetime]:
    """Any whole second of 2026 (UTC), or one within an hour before a daylight-saving change."""
    anywhere = st.datetimes(
        datetime(2026, 1, 1), datetime(2026, 12, 31), timezones=st.just(UTC)
    ).map(lambda t: t.replace(microsecond=0))
    near_change = st.builds(
        lambda change, before: change - timedelta(seconds=before),
        st.sampled_from(TRANSITIONS),
        st.integers(0, 3600),
    )
    return st.one_of(anywhere, near_change)
