"""The paper's study predicted over the pre-registered seeds, and the decision system
against the baselines that could beat it: one JSON object on stdout.

For each seed one study of ``--sessions`` participants of 30 minutes, each coming
``--repeat`` times, runs with the decision system's chooser (``dms``: the paper's, the
best of the predicted ranking) and with each chooser of ``--choosers`` on the same
participants. Printed:

- ``metrics``: per Table 4 metric (and failure total, and outcome), the decision
  system's mean over the seeds with its 95 % interval (``ci``), the range of 95 % of
  single studies (``studies``), the paper's value and whether it is an input or a
  prediction (``role``);
- ``baselines``: per chooser, per metric, the paired difference chooser - dms with a
  bootstrap 95 % interval over the seeds, pooled, and per visit under ``visits``;
- ``targets``: the default against ``popular`` and ``greedy`` within +0.05 cancels a
  session and -0.02 liking of the robot's choices (non-inferior: the interval's bound
  on the wrong side stays within the margin), at the first visit and the last; and
  above ``popular`` on liking at the last visit on ``heldout`` with the interval
  excluding 0. Each says ``met`` true or false, with the figure it was judged on;
- ``wall_s``.

Run: ``.venv/bin/python bench/bench_study.py [--quick] [--seeds 0-99]
[--choosers popular,greedy|none] [--population paper|heldout] [--repeat 5] [--jobs 2]``
(about 10 s a study of 30 participants on the dev machine; ``--jobs`` runs studies side
by side, with the same results).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from typing import Any, cast

from sim.baselines import BASELINES, ChooserName
from sim.compare import metrics_json
from sim.prediction import (
    PREREGISTERED_SEEDS,
    Difference,
    paired,
    paired_by_visit,
    role,
    run_seeds,
    summary,
)
from sim.study import study_settings

CANCEL_MARGIN = 0.05
"""How many more cancels a session than a baseline the default may cost (non-inferior)."""
LIKING_MARGIN = 0.02
"""How much lower a true liking of the robot's choices than a baseline's it may get."""


def non_inferior(versus: dict[str, Difference]) -> dict[str, Any]:
    """Whether the default is within the margins of a baseline (``versus``: baseline -
    dms): its cancels' excess and its liking's shortfall bounded by the intervals."""
    cancels, liking = versus["cancels_per_session"], versus["robot_choice_liking"]
    worst_cancels = -cancels.ci[0]  # dms - baseline, at its upper bound
    worst_liking = -liking.ci[1]  # dms - baseline, at its lower bound
    finite = math.isfinite(worst_cancels) and math.isfinite(worst_liking)
    return {
        "met": finite and worst_cancels <= CANCEL_MARGIN and worst_liking >= -LIKING_MARGIN,
        "cancels_dms_minus_baseline_upper": _round(worst_cancels),
        "liking_dms_minus_baseline_lower": _round(worst_liking),
    }


def above(versus: dict[str, Difference]) -> dict[str, Any]:
    """Whether the default's liking is above a baseline's, the interval excluding 0."""
    liking = versus["robot_choice_liking"]
    return {
        "met": math.isfinite(liking.ci[1]) and liking.ci[1] < 0.0,
        "liking_dms_minus_baseline": _round(-liking.diff),
        "ci": [_round(-liking.ci[1]), _round(-liking.ci[0])],
    }


def _round(value: float) -> float | None:
    return round(value, 4) if math.isfinite(value) else None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="seeds 0-2, 6 participants")
    parser.add_argument("--seeds", help="FIRST-LAST (default: the pre-registered 0-99)")
    parser.add_argument(
        "--choosers", help="choosers beside dms, comma-separated, or none (default: all)"
    )
    parser.add_argument("--sessions", type=int, default=30)
    parser.add_argument("--repeat", type=int, default=1, help="visits of each participant")
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
    sessions = 6 if args.quick else args.sessions
    if args.choosers == "none":
        others: list[ChooserName] = []
    elif args.choosers:
        others = [cast(ChooserName, c) for c in args.choosers.split(",")]
    else:
        others = list(BASELINES)
    wall = time.perf_counter()
    settings = study_settings()

    def run(chooser: ChooserName) -> list:  # type: ignore[type-arg]
        print(f"bench_study: {chooser} on {len(seeds)} seeds", file=sys.stderr, flush=True)
        return run_seeds(
            seeds,
            sessions,
            30.0,
            settings=settings,
            chooser=chooser,
            population=args.population,
            jobs=args.jobs,
            repeat=args.repeat,
        )

    dms = run("dms")
    estimates = summary(dms)
    pooled: dict[str, dict[str, Difference]] = {}
    visits: dict[str, list[dict[str, Difference]]] = {}
    for name in others:
        results = run(name)
        pooled[name] = paired(dms, results)
        visits[name] = paired_by_visit(dms, results)
    targets: dict[str, Any] = {}
    for name in ("popular", "greedy"):
        if name in visits:
            targets[f"non_inferior_to_{name}_first_visit"] = non_inferior(visits[name][0])
            targets[f"non_inferior_to_{name}_last_visit"] = non_inferior(visits[name][-1])
    if "popular" in visits and args.population == "heldout":
        targets["above_popular_on_liking_last_visit"] = above(visits["popular"][-1])
    out = {
        "seeds": [seeds[0], seeds[-1]],
        "sessions": sessions,
        "repeat": args.repeat,
        "population": args.population,
        "metrics": {k: {**e.to_json(), "role": role(k)} for k, e in estimates.items()},
        "baselines": {
            name: {
                "pooled": metrics_json(pooled[name]),
                "visits": [metrics_json(v) for v in visits[name]],
            }
            for name in others
        },
        "targets": targets,
    }
    out["wall_s"] = round(time.perf_counter() - wall, 1)
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
