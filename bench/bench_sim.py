"""Benchmarks of the simulation: one JSON object on stdout.

- ``session_30min_s``: a 30-minute session with one simulated user (``alice``), through
  the full stack on the virtual clock; target <= 0.2 s. ``session_setup_s``
  is the time to build that stack (open SQLite, load rules and behaviors), once per
  session. Best of three identical seeded runs, with their median beside it.
- ``study_30x30_s``: ``dms sim study`` with its defaults (30 sessions of 30 minutes);
  target <= 60 s.
- ``longterm_30d_3u_s`` and ``longterm_peak_rss_mb``: ``dms sim longterm`` for 30 days
  with 3 users; targets <= 10 s and <= 300 MB. It runs first, so the
  process's peak resident size is its own.

``--quick``: 2 days, a 5-minute session run once and a study of 3 sessions of 5 minutes.

Run: ``.venv/bin/python bench/bench_sim.py [--only longterm|session|study]... [--quick]``
"""

from __future__ import annotations

import argparse
import json
import random
import statistics
import time

from sim.harness import Simulation
from sim.longterm import run_longterm
from sim.persona import load_persona
from sim.study import run_study
from sim.user import SimulatedUser


def bench_session(minutes: float = 30.0, runs: int = 3) -> dict[str, float]:
    """The session's own time (best and median of ``runs`` identical seeded runs);
    building the stack (SQLite, rules, behaviors) is reported apart."""
    with Simulation(seed=0):
        pass  # first stack of the process: imports and the cached seed model, not measured
    times, setups = [], []
    for _ in range(runs):
        wall = time.perf_counter()
        with Simulation(seed=1) as sim:
            ready = time.perf_counter()
            sim.seat(SimulatedUser(load_persona("alice"), random.Random(1)))
            sim.run_for(minutes * 60)
            times.append(time.perf_counter() - ready)
            setups.append(ready - wall)
            ticks, decisions = sim.ticks, len(sim.decisions)
    best = min(times)
    return {
        "session_30min_s": round(best, 3),
        "session_30min_median_s": round(statistics.median(times), 3),
        "session_setup_s": round(min(setups), 3),
        "session_ticks": ticks,
        "session_decisions": decisions,
        "session_tick_us": round(1e6 * best / max(1, ticks), 1),
    }


CASES = ("longterm", "session", "study")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--only",
        choices=CASES,
        action="append",
        help="run this case alone (repeatable); default: all three",
    )
    parser.add_argument("--quick", action="store_true", help="small sizes, the same code (smoke)")
    args = parser.parse_args()
    cases = args.only or list(CASES)
    quick = args.quick
    out: dict[str, object] = {"benchmark": "sim", "quick": quick}
    if "longterm" in cases:  # first: the process's peak resident size is its own
        longterm = run_longterm(days=2 if quick else 30, users=3, seed=0)
        out.update(
            {
                "longterm_30d_3u_s": round(longterm.wall_s, 3),
                "longterm_ticks": longterm.ticks,
                "longterm_visits": longterm.visits,
                "longterm_decisions": longterm.decisions,
                "longterm_peak_rss_mb": round(longterm.peak_rss_mb, 1),
            }
        )
    if "session" in cases:
        out.update(bench_session(5.0, 1) if quick else bench_session())
    if "study" in cases:
        study = run_study(sessions=3 if quick else 30, minutes=5 if quick else 30, seed=0)
        out["study_30x30_s"] = round(study.wall_s, 3)
        summary = study.to_json()
        out["study_activities_per_session"] = summary["activities_per_session"]
    out["targets"] = {
        "session_30min_s": 0.2,
        "study_30x30_s": 60.0,
        "longterm_30d_3u_s": 10.0,
        "longterm_peak_rss_mb": 300.0,
    }
    print(json.dumps(out))


if __name__ == "__main__":
    main()
