"""Recovery of the participants' inputs by ``dms sim fit``: one JSON object on stdout.

Each replication draws true inputs (the calibration's participant habits, each moved by
a factor in 0.75-1.25, a share of menus left to the robot in 0.1-0.4 and of questions
left unanswered in 0-0.05), runs the study with simulated people who have them
(``sim.study.run_study``, their sessions' interaction events recorded as the daemon
records them), fits the inputs back from the events alone and checks whether each
true value (each bound of a range) lies inside its interval. Printed:

- ``coverage``: per input, the share of replications whose interval holds the truth
  (per bound for a range), and ``overall`` over every value checked;
- ``level``, ``replications``, ``people``, ``minutes``, ``bootstrap``, ``wall_s``.

Run: ``.venv/bin/python bench/bench_fit.py [--quick] [--replications 40] [--people 30]``
(``--quick``: 4 replications of 12 people for 20 minutes, for CI).
"""

from __future__ import annotations

import argparse
import json
import random
import sys
import time
from collections import defaultdict

from sim import fit
from sim.calibration import DEFAULT, Calibration
from sim.study import run_study, study_settings

MOVED = (
    "answer_delay_s",
    "menu_delay_s",
    "rating_delay_s",
    "stop_after_s",
    "error_rate",
    "screen_rate",
    "continue_rate",
)
"""The calibration's inputs each replication moves (the fitted ones it holds)."""


def truth(rng: random.Random) -> Calibration:
    """True inputs for one replication, around the calibration's."""
    values = dict(DEFAULT.values)
    for name in MOVED:
        value, factor = values[name], rng.uniform(0.75, 1.25)
        if isinstance(value, tuple):
            values[name] = (value[0] * factor, value[1] * factor)
        else:
            values[name] = min(1.0, value * factor)
    values["decline_menu_rate"] = rng.uniform(0.1, 0.4)
    values["no_answer_rate"] = rng.uniform(0.0, 0.05)
    return Calibration(tuple(values.items()))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="4 replications of 12 people")
    parser.add_argument("--replications", type=int, default=40)
    parser.add_argument("--people", type=int, default=30)
    parser.add_argument("--minutes", type=float, default=30.0)
    parser.add_argument("--bootstrap", type=int, default=fit.BOOTSTRAP)
    args = parser.parse_args()
    reps, people, minutes = args.replications, args.people, args.minutes
    if args.quick:
        reps, people, minutes = 4, 12, 20.0
    wall = time.perf_counter()
    settings = study_settings()
    hits: dict[str, list[bool]] = defaultdict(list)
    for rep in range(reps):
        true = truth(random.Random(f"bench_fit/{rep}"))
        result = run_study(
            people, minutes, seed=rep, settings=settings, calibration=true, record_events=True
        )
        fitted = fit.fit(fit.people(result.events), bootstrap=args.bootstrap, seed=rep)
        for item in fitted:
            value = fit.truth_of(true, item.name)
            if value is None or item.estimate is None:
                continue
            hits[item.name].extend(item.covers(value))
        so_far = [hit for values in hits.values() for hit in values]
        print(
            f"bench_fit: replication {rep + 1}/{reps}, coverage so far"
            f" {sum(so_far) / max(1, len(so_far)):.3f}",
            file=sys.stderr,
            flush=True,
        )
    every = [hit for values in hits.values() for hit in values]
    coverage = {name: round(sum(values) / len(values), 3) for name, values in hits.items()}
    print(
        json.dumps(
            {
                "coverage": {**coverage, "overall": round(sum(every) / max(1, len(every)), 3)},
                "checked": len(every),
                "level": fit.LEVEL,
                "replications": reps,
                "people": people,
                "minutes": minutes,
                "bootstrap": args.bootstrap,
                "wall_s": round(time.perf_counter() - wall, 1),
            },
            indent=2,
        )
    )


if __name__ == "__main__":
    main()
