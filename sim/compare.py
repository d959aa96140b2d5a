"""``dms sim compare``: two designs on the same participants, metric by metric.

A design is a dms configuration (TOML) and optionally a rules file. Both run the study
with the same seed, so session ``i`` of each has the same participant (the population
is drawn from its own generator, :func:`sim.study.participants`); the difference of a
metric is taken per session and its mean gets a bootstrap 95 % interval
(``scipy.stats.bootstrap``, BCa, resampling the paired differences). An interval that
excludes 0 says the designs differ on that metric beyond the run's own noise.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from dms.config import Settings
from sim.study import LABELS, METRICS, ProactivityLevel, StudyResult, run_study

BOOTSTRAP_RESAMPLES = 2000


@dataclass(frozen=True)
class MetricComparison:
    a: float
    b: float
    diff: float
    """Mean of the paired differences b - a."""
    ci: tuple[float, float]


def _paired(a: StudyResult, b: StudyResult, key: str) -> tuple[list[float], list[float]]:
    xs, ys = [], []
    for sa, sb in zip(a.metric_values()[key], b.metric_values()[key], strict=True):
        if sa is not None and sb is not None:
            xs.append(sa)
            ys.append(sb)
    return xs, ys


def bootstrap_ci(diffs: list[float], seed: int) -> tuple[float, float]:
    """95 % bootstrap interval of the mean of ``diffs`` (BCa; percentile when BCa cannot
    be computed, e.g. every difference equal)."""
    import numpy as np
    from scipy.stats import bootstrap

    if not diffs:
        return (math.nan, math.nan)
    data = np.asarray(diffs, dtype=float)
    if np.all(data == data[0]):
        return (float(data[0]), float(data[0]))
    rng = np.random.default_rng(seed)
    result = bootstrap(
        (data,), np.mean, n_resamples=BOOTSTRAP_RESAMPLES, confidence_level=0.95, rng=rng
    )
    low, high = result.confidence_interval
    if not (math.isfinite(low) and math.isfinite(high)):
        result = bootstrap(
            (data,),
            np.mean,
            n_resamples=BOOTSTRAP_RESAMPLES,
            method="percentile",
            rng=np.random.default_rng(seed),
        )
        low, high = result.confidence_interval
    return (float(low), float(high))


def compare(
    a: Settings,
    b: Settings,
    sessions: int = 30,
    minutes: float = 30.0,
    seed: int = 0,
    proactivity: ProactivityLevel = "moderate",
    progress: Callable[[str, int], None] | None = None,
) -> dict[str, MetricComparison]:
    """Run both designs on the same seed and participants; compare each Table 4 metric."""
    results = []
    for label, settings in (("A", a), ("B", b)):

        def told(done: int, label: str = label) -> None:
            if progress is not None:
                progress(label, done)

        results.append(run_study(sessions, minutes, proactivity, seed, settings, told))
    out: dict[str, MetricComparison] = {}
    for key in METRICS:
        xs, ys = _paired(results[0], results[1], key)
        diffs = [y - x for x, y in zip(xs, ys, strict=True)]
        mean_a = sum(xs) / len(xs) if xs else math.nan
        mean_b = sum(ys) / len(ys) if ys else math.nan
        diff = sum(diffs) / len(diffs) if diffs else math.nan
        out[key] = MetricComparison(mean_a, mean_b, diff, bootstrap_ci(diffs, seed))
    return out


def _number(value: float) -> float | None:
    return round(value, 4) if math.isfinite(value) else None


def to_json(comparison: dict[str, MetricComparison]) -> dict[str, Any]:
    """``{"metrics": {name: {"a", "b", "diff", "ci": [lo, hi]}}}``; null where no session
    pair has the metric (e.g. no activity ended, so no time to change)."""
    return {
        "metrics": {
            key: {
                "a": _number(c.a),
                "b": _number(c.b),
                "diff": _number(c.diff),
                "ci": [_number(c.ci[0]), _number(c.ci[1])]
                if math.isfinite(c.ci[0]) and math.isfinite(c.ci[1])
                else None,
            }
            for key, c in comparison.items()
        }
    }


def table(comparison: dict[str, MetricComparison]) -> str:
    """One line per metric: both means, the paired difference and its interval."""
    lines = [
        f"{'Metric':<38} {'A':>9} {'B':>9} {'B - A':>9}  95 % CI",
        "-" * 84,
    ]
    for key, c in comparison.items():
        mark = "" if c.ci[0] <= 0.0 <= c.ci[1] else "  *"
        lines.append(
            f"{LABELS[key]:<38} {c.a:9.2f} {c.b:9.2f} {c.diff:9.2f}  "
            f"[{c.ci[0]:.2f}, {c.ci[1]:.2f}]{mark}"
        )
    lines.append("* the interval excludes 0: the designs differ on this metric")
    return "\n".join(lines)
