"""The shortcuts a long simulation takes give what the long way gives.

The long-term tracker reads the motivation model's own state each tick instead of
DmsState's snapshot, and a manager answers with its last reply while nothing in it
changed. Each test runs the long way beside the short one, on a simulated morning with
a visitor, and compares them exactly (fixed seeds: the numbers must be the same
floats, not close ones).
"""

from __future__ import annotations

import math
import random
from datetime import UTC, datetime
from typing import Any

import pytest

from dms.controller import TickRecord
from managers import ManagerReply, ManagerStatus
from sim.harness import Simulation
from sim.longterm import _Tracker
from sim.persona import load_persona
from sim.user import SimulatedUser

START = datetime(2026, 11, 23, 6, 0, tzinfo=UTC)


def _morning(sim: Simulation) -> None:
    """Two idle hours (idle steps), a visit of 20 minutes, an idle hour."""
    sim.idle_step_s = 300.0
    user = SimulatedUser(load_persona("alice"), random.Random(4))
    sim.at(2 * 3600, lambda: sim.seat(user))
    sim.at(2 * 3600 + 1200, sim.unseat)
    sim.unseat()
    sim.run_until(3.5 * 3600)


class _FromSnapshots:
    """The long-term tracker's motivation figures the way it took them before: from
    each tick's MotivationSnapshot."""

    def __init__(self, sim: Simulation) -> None:
        self.sim = sim
        self.drives_max: dict[str, float] = {}
        self.area = 0.0
        self.last: tuple[float, float] | None = None
        self.samples: list[tuple[float, dict[str, float], float]] = []

    def on_tick(self, record: TickRecord) -> None:
        t, motivation = self.sim.t, record.motivation
        if self.last is not None:
            self.area += self.last[1] * (t - self.last[0])
        for name, value in motivation.drives.items():
            if value > self.drives_max.get(name, -math.inf):
                self.drives_max[name] = value
        self.last = (t, motivation.wellbeing)
        self.samples.append((t, dict(motivation.drives), motivation.wellbeing))


@pytest.mark.parametrize("batch", [_Tracker.BATCH_TICKS, 7])
def test_the_tracker_gives_what_the_snapshots_give(batch: int) -> None:
    """Summed in batches (of 7 ticks too: hundreds of batch ends), the same floats."""
    with Simulation(seed=2, start=START) as sim:
        tracker = _Tracker(START, sim.controller.deps.motivation)
        tracker.BATCH_TICKS = batch
        reference = _FromSnapshots(sim)
        sim.tick_listeners += [lambda record: tracker.on_tick(sim.t, record), reference.on_tick]
        _morning(sim)
        assert sim.ticks > 2000, "the visit should tick at 2 Hz"
    assert tracker.drives_max == reference.drives_max
    assert tracker.wellbeing_area == reference.area
    sampled = {t: (drives, wellbeing) for t, drives, wellbeing in reference.samples}
    assert tracker.samples, "a sample every five minutes"
    for t, drives, wellbeing in tracker.samples:
        assert sampled[t] == (drives, wellbeing)


def test_a_manager_answers_again_only_with_what_still_holds() -> None:
    checked = 0

    with Simulation(seed=2, start=START) as sim:
        for manager in sim.controller.managers.values():
            tick = manager.tick

            def checking(now: datetime, manager: Any = manager, tick: Any = tick) -> ManagerReply:
                nonlocal checked
                reply: ManagerReply = tick(now)
                activity = manager.activity
                if reply.status in (ManagerStatus.RUNNING, ManagerStatus.PAUSED):
                    assert activity is not None
                    assert reply.activity == manager.activity_name
                    assert reply.state == activity.state_path
                    assert reply.redirect is None and reply.detail is None and reply.data is None
                    paused = activity.status is not None and activity.status.value == "paused"
                    assert (reply.status is ManagerStatus.PAUSED) == paused
                    checked += 1
                return reply

            manager.tick = checking  # type: ignore[method-assign]
        _morning(sim)
    assert checked > 2000


def test_the_tracker_accounts_each_span_and_its_hours() -> None:
    """An activity's time is accounted when it ends: the spans, split at the hours."""
    with Simulation(seed=2, start=START) as sim:
        tracker = _Tracker(START, sim.controller.deps.motivation)
        sim.tick_listeners.append(lambda record: tracker.on_tick(sim.t, record))
        _morning(sim)
        tracker.finish(sim.t)
    spans: dict[str, float] = {}
    for name, t0, t1 in tracker.spans:
        spans[name] = spans.get(name, 0.0) + t1 - t0
    assert len(spans) >= 2, "idle behaviors and the visitor's activities"
    assert tracker.spans[-1][2] == 3.5 * 3600, "the last span runs to the end"
    assert set(tracker.activity_seconds) == set(spans)
    for name, seconds in spans.items():
        assert math.isclose(tracker.activity_seconds[name], seconds, abs_tol=1e-6)
        by_hour = sum(hours.get(name, 0.0) for hours in tracker.by_hour.values())
        assert math.isclose(by_hour, seconds, abs_tol=1e-6)
    assert sum(tracker.by_hour[6].values()) == 3600.0, "06:00-07:00, all of it"
