"""Benchmark: the motivation model's step, a 30-day advance, 30 idle days at 2 Hz.

The shipped configuration (rest, social, play) in Europe/Madrid, no user, from the
initial state at 2026-11-23 00:00 UTC. Measured:

- ``step_us``: one ``MotivationModel.step`` (three drives, 0.5 s), p50 and p99 over
  20,000 ticks of an idle robot whose behavior follows its dominant motivation;
- ``advance_30d_s``: ``advance`` over 30 days at 0.5 s ticks (5,184,000 ticks, the
  dominant motivation checked at each), nothing running;
- ``follow_30d_s``: ``simulate(follow=True)`` over 30 days at 2 Hz, the behavior
  following the dominant motivation tick by tick as the daemon's step 4 does
  (target <= 2 s);
- ``loop_1h_s``: the same as a plain Python loop of ``step`` for one simulated hour
  (7,200 ticks), and ``loop_30d_extrapolated_s`` = 720 times that (not run: labelled);
- ``loop_vs_simulate_max_diff``: the largest drive difference between that hour of
  ``step`` and ``simulate`` (they must agree within 1e-6).

Totals are the best of ``--repeat`` runs. Prints one JSON object.

    .venv/bin/python bench/bench_motivation.py [--repeat N] [--quick]
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from collections.abc import Callable
from datetime import UTC, datetime, timedelta
from zoneinfo import ZoneInfo

import numpy as np

from motivation import MotivationModel, MotivationState, advance, simulate

START = datetime(2026, 11, 23, 0, 0, tzinfo=UTC)
TICK_S = 0.5
DAYS = 30


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))]


def step_loop(model: MotivationModel, ticks: int) -> tuple[list[float], list[MotivationState]]:
    """Step an idle robot ``ticks`` times; the duration of each step in seconds, the states."""
    state = model.initial_state(START)
    nothing = model.no_stimuli()
    durations: list[float] = []
    states: list[MotivationState] = []
    for k in range(ticks):
        now = START + timedelta(seconds=(k + 1) * TICK_S)
        running = model.behavior(state)
        t0 = time.perf_counter()
        state = model.step(state, TICK_S, nothing, running, now)
        durations.append(time.perf_counter() - t0)
        states.append(state)
    return durations, states


def best_of(repeat: int, job: Callable[[], object]) -> float:
    """The shortest wall time of ``repeat`` calls of ``job``."""
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        job()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--quick", action="store_true", help="3 days, once (smoke)")
    args = parser.parse_args()
    days = 3 if args.quick else DAYS
    repeat = 1 if args.quick else args.repeat
    model = MotivationModel(zone=ZoneInfo("Europe/Madrid"))
    state = model.initial_state(START)
    nothing = model.no_stimuli()
    seconds = days * 86_400.0

    step_loop(model, 2000)  # warm up numpy and the caches
    step_durations, _ = step_loop(model, 20_000)
    step_us = [d * 1e6 for d in step_durations]

    advance_s = best_of(
        repeat, lambda: advance(model, state, seconds, nothing, None, START, TICK_S)
    )
    follow_s = best_of(
        repeat,
        lambda: simulate(model, state, START, seconds, nothing, follow=True, every=0),
    )
    run = simulate(model, state, START, seconds, nothing, follow=True, every=0)

    hour_ticks = int(3600 / TICK_S)
    t0 = time.perf_counter()
    _, states = step_loop(model, hour_ticks)
    loop_1h_s = time.perf_counter() - t0
    hour = simulate(model, state, START, 3600.0, nothing, follow=True, every=1)
    difference = float(np.max(np.abs(hour.drives - np.array([s.drives for s in states]))))
    same_dominant = hour.dominant.tolist() == [s.dominant for s in states]

    print(
        json.dumps(
            {
                "drives": list(model.names),
                "step_us": {
                    "p50": round(statistics.median(step_us), 1),
                    "p99": round(percentile(step_us, 0.99), 1),
                    "ticks": len(step_us),
                },
                "advance_30d_s": round(advance_s, 3),
                "follow_30d_s": round(follow_s, 3),
                "follow_30d_ticks": run.ticks,
                "follow_30d_behavior_changes": run.switches,
                "follow_target_s": 2.0,
                "loop_1h_s": round(loop_1h_s, 3),
                "loop_30d_extrapolated_s": round(loop_1h_s * 24 * DAYS, 1),
                "days": days,
                "loop_vs_simulate_max_diff": difference,
                "loop_vs_simulate_same_dominant": same_dominant,
                "repeat": repeat,
            }
        )
    )


if __name__ == "__main__":
    main()
