"""``dms sim compare``: two designs or two choosers on the same participants, metric by metric.

A design is a dms configuration (TOML) and optionally a rules file; a chooser is what
picks the robot's own choices (:mod:`sim.baselines`: the decision system's ``dms`` or a
baseline). Both sides run the study with the same seeds, so session ``i`` of each has
the same participant (the population is drawn from its own generator,
:func:`sim.study.participants`); the difference of a metric is taken per session pair,
and its mean gets a bootstrap 95 % interval (``scipy.stats.bootstrap``, BCa): over the
session pairs with one seed, over the seeds' mean differences with several. An interval
that excludes 0 says the two sides differ on that metric beyond the run's own noise.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from dms.config import Settings
from sim.baselines import ChooserName
from sim.calibration import DEFAULT, Calibration
from sim.population import Population
from sim.prediction import Difference, bootstrap_ci, paired, paired_by_visit, run_seeds
from sim.study import ProactivityLevel
from sim.table4 import LABELS

MetricComparison = Difference
__all__ = [
    "Comparison",
    "MetricComparison",
    "bootstrap_ci",
    "compare",
    "metrics_json",
    "table",
    "to_json",
]


@dataclass(frozen=True)
class Comparison:
    """B - A per metric over every session (``metrics``) and per visit (``visits``: one
    entry when each participant came once)."""

    metrics: dict[str, MetricComparison]
    visits: list[dict[str, MetricComparison]]


def compare(
    a: Settings,
    b: Settings,
    sessions: int = 30,
    minutes: float = 30.0,
    seed: int = 0,
    proactivity: ProactivityLevel = "moderate",
    progress: Callable[[str, int], None] | None = None,
    *,
    chooser_a: ChooserName = "dms",
    chooser_b: ChooserName = "dms",
    seeds: Sequence[int] | None = None,
    population: Population = "paper",
    calibration: Calibration = DEFAULT,
    repeat: int = 1,
) -> Comparison:
    """Run both sides on the same seeds and participants, each coming ``repeat`` times;
    compare each metric (Table 4's and what the participants got: the true liking of the
    robot's choices, cancels per robot choice, time in liked activities), pooled and
    visit by visit."""
    chosen = list(seeds) if seeds is not None else [seed]
    results = []
    for label, settings, chooser in (("A", a, chooser_a), ("B", b, chooser_b)):

        def told(done: int, label: str = label) -> None:
            if progress is not None:
                progress(label, done * sessions * repeat)

        results.append(
            run_seeds(
                chosen,
                sessions,
                minutes,
                proactivity,
                settings,
                chooser=chooser,
                population=population,
                calibration=calibration,
                progress=told,
                repeat=repeat,
            )
        )
    return Comparison(paired(results[0], results[1]), paired_by_visit(results[0], results[1]))


def _number(value: float) -> float | None:
    return round(value, 4) if math.isfinite(value) else None


def metrics_json(metrics: dict[str, MetricComparison]) -> dict[str, Any]:
    """``{name: {"a", "b", "diff", "ci": [lo, hi]}}``; null where no session pair has the
    metric (e.g. no activity ended, so no time to change)."""
    return {
        key: {
            "a": _number(c.a),
            "b": _number(c.b),
            "diff": _number(c.diff),
            "ci": [_number(c.ci[0]), _number(c.ci[1])]
            if math.isfinite(c.ci[0]) and math.isfinite(c.ci[1])
            else None,
        }
        for key, c in metrics.items()
    }


def to_json(comparison: Comparison) -> dict[str, Any]:
    """``{"metrics": {...}, "visits": [{"visit": 1, "metrics": {...}}, ...]}``."""
    return {
        "metrics": metrics_json(comparison.metrics),
        "visits": [
            {"visit": number, "metrics": metrics_json(metrics)}
            for number, metrics in enumerate(comparison.visits, start=1)
        ],
    }


VISIT_ROWS = (
    "robot_choice_liking",
    "robot_choice_cancel_rate",
    "cancels_per_session",
    "liked_time_s",
)
"""The rows the text table repeats visit by visit (the JSON has every metric)."""


def table(comparison: Comparison) -> str:
    """One line per metric: both means, the paired difference and its interval; then,
    when participants came more than once, what they got visit by visit."""
    lines = [
        f"{'Metric':<38} {'A':>9} {'B':>9} {'B - A':>9}  95 % CI",
        "-" * 84,
    ]
    lines += _rows(comparison.metrics)
    if len(comparison.visits) > 1:
        for number, metrics in enumerate(comparison.visits, start=1):
            lines.append(f"visit {number}")
            lines += _rows({k: metrics[k] for k in VISIT_ROWS if k in metrics})
    lines.append("* the interval excludes 0: the two sides differ on this metric")
    return "\n".join(lines)


def _rows(metrics: dict[str, MetricComparison]) -> list[str]:
    lines = []
    for key, c in metrics.items():
        if not math.isfinite(c.diff):
            lines.append(f"{LABELS[key]:<38} {'(no session pair has it)':>29}")
            continue
        mark = "" if c.ci[0] <= 0.0 <= c.ci[1] else "  *"
        lines.append(
            f"{LABELS[key]:<38} {c.a:9.2f} {c.b:9.2f} {c.diff:9.2f}  "
            f"[{c.ci[0]:.2f}, {c.ci[1]:.2f}]{mark}"
        )
    return lines
