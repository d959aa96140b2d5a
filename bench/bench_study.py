"""The paper's study predicted over the pre-registered seeds: one JSON object on stdout.

For each seed (0-99; ``--quick``: 0-2) one study of 30 participants of 30 minutes runs
with the decision system's chooser and with each baseline (``random``, ``fixed``,
``least_liked``, ``oracle``) on the same participants. Printed:

- ``metrics``: per Table 4 metric (and failure total, and outcome), the decision
  system's mean over the seeds with its 95 % interval (``ci``), the range of 95 % of
  single studies (``studies``), the paper's value and whether it is an input or a
  prediction (``role``);
- ``baselines``: per baseline, per metric, the paired difference baseline - dms with a
  bootstrap 95 % interval over the seeds;
- ``wall_s``.

Run: ``.venv/bin/python bench/bench_study.py [--quick] [--seeds 0-99]
[--choosers random,oracle] [--jobs 2]`` (about 10 s a study on the dev machine: 100 seeds
and four baselines take about 85 minutes of one core; ``--jobs`` runs studies side by
side, with the same results).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from typing import cast

from sim.baselines import BASELINES, ChooserName
from sim.compare import metrics_json
from sim.prediction import PREREGISTERED_SEEDS, paired, role, run_seeds, summary
from sim.study import study_settings


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="seeds 0-2 only")
    parser.add_argument("--seeds", help="FIRST-LAST (default: the pre-registered 0-99)")
    parser.add_argument("--choosers", help="baselines, comma-separated (default: all)")
    parser.add_argument("--sessions", type=int, default=30)
    parser.add_argument("--population", default="paper", choices=("paper", "heldout"))
    parser.add_argument(
        "--jobs", type=int, default=1, help="studies run at once (worker processes)"
    )
    args = parser.parse_args()
    if args.seeds:
        first, last = args.seeds.split("-")
        seeds = list(range(int(first), int(last) + 1))
    else:
        seeds = list(PREREGISTERED_SEEDS[:3] if args.quick else PREREGISTERED_SEEDS)
    baselines = (
        [cast(ChooserName, c) for c in args.choosers.split(",")]
        if args.choosers
        else list(BASELINES)
    )
    wall = time.perf_counter()
    settings = study_settings()

    def run(chooser: ChooserName) -> list:  # type: ignore[type-arg]
        print(f"bench_study: {chooser} on {len(seeds)} seeds", file=sys.stderr, flush=True)
        return run_seeds(
            seeds,
            args.sessions,
            30.0,
            settings=settings,
            chooser=chooser,
            population=args.population,
            jobs=args.jobs,
        )

    dms = run("dms")
    estimates = summary(dms)
    out = {
        "seeds": [seeds[0], seeds[-1]],
        "sessions": args.sessions,
        "population": args.population,
        "metrics": {k: {**e.to_json(), "role": role(k)} for k, e in estimates.items()},
        "baselines": {name: metrics_json(paired(dms, run(name))) for name in baselines},
    }
    out["wall_s"] = round(time.perf_counter() - wall, 1)
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
