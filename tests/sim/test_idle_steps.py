"""Skipping the ticks of an empty room loses nothing the motivation decides.

A long run ticks an empty room every ``idle_step_s`` instead of at 2 Hz, but never
past the tick where the motivated behavior changes; so the motivation's decisions
(cancel for ``motivation_changed``) fall on the same ticks as at 2 Hz throughout.
"""

from __future__ import annotations

from datetime import UTC, datetime

from dms.config import Settings
from sim.harness import Simulation

START = datetime(2026, 11, 23, 13, 0, tzinfo=UTC)


def _changes(idle_step_s: float | None, hours: float) -> tuple[list[tuple[float, str]], int]:
    # Playful and a little lonely at the start: dance and calls for attention soon.
    drives = {"play": {"initial": 46.0}, "social": {"initial": 55.0}, "rest": {"initial": 50.0}}
    settings = Settings(motivation={"drives": drives})
    with Simulation(settings, seed=3, start=START, with_memory=False) as sim:
        sim.idle_step_s = idle_step_s
        sim.unseat()
        sim.run_for(hours * 3600)
        changes = [
            (timed.t, timed.decision.activity or "")
            for timed in sim.decisions
            if timed.decision.reason == "motivation_changed"
        ]
        return changes, sim.ticks


def test_idle_steps_keep_the_motivation_changes_on_the_2hz_ticks() -> None:
    every_tick, ticks_2hz = _changes(None, 3.5)
    stepped, ticks_stepped = _changes(300.0, 3.5)
    assert len(every_tick) >= 2, "the window should hold some changes of motivation"
    assert stepped == every_tick
    assert ticks_stepped < ticks_2hz / 20
