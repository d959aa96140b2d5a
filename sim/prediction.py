"""Many seeds of the study: each metric's mean with a 95 % interval, beside the paper's.

The seeds are fixed before looking at any result (:data:`PREREGISTERED_SEEDS`, 0-99).
Each seed is one study like the paper's (30 participants); per metric two intervals are
reported:

- ``ci``: the 95 % interval of the mean over seeds (Student's t): where the simulation's
  expected value lies;
- ``studies``: the 2.5th-97.5th percentiles of the single studies' means: where one
  study of 30 participants falls, the range the paper's single study is to be judged by.

Paired comparisons (:func:`paired`) run two choosers on the same seeds and participants
and bootstrap the mean difference over seeds (each seed's mean difference is one
observation; with one seed, each session pair is).
"""

from __future__ import annotations

import functools
import math
import statistics
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from typing import Any

from dms.config import Settings
from sim.baselines import ChooserName
from sim.calibration import DEFAULT, Calibration
from sim.population import Population
from sim.study import ProactivityLevel, StudyResult, run_study
from sim.table4 import (
    INPUT_METRICS,
    LABELS,
    METRICS,
    OUTCOMES,
    PAPER,
    PAPER_FAILURES,
    PARTLY_INPUT,
    failures,
    rows,
)

PREREGISTERED_SEEDS: tuple[int, ...] = tuple(range(100))
"""The seeds every reported figure is computed on, fixed before the first run."""
FAILURES = tuple(PAPER_FAILURES)
BOOTSTRAP_RESAMPLES = 2000


@dataclass(frozen=True)
class Estimate:
    """One metric over seeds."""

    mean: float
    ci: tuple[float, float]
    studies: tuple[float, float]
    paper: float | None

    def to_json(self) -> dict[str, Any]:
        return {
            "mean": _round(self.mean),
            "ci": [_round(self.ci[0]), _round(self.ci[1])],
            "studies": [_round(self.studies[0]), _round(self.studies[1])],
            "paper": self.paper,
        }


def run_seeds(
    seeds: Sequence[int],
    sessions: int = 30,
    minutes: float = 30.0,
    proactivity: ProactivityLevel = "moderate",
    settings: Settings | None = None,
    *,
    chooser: ChooserName = "dms",
    population: Population = "paper",
    calibration: Calibration = DEFAULT,
    progress: Callable[[int], None] | None = None,
    jobs: int = 1,
    repeat: int = 1,
) -> list[StudyResult]:
    """One study per seed, in the order of ``seeds``, each participant coming ``repeat``
    times; ``progress`` is told the number of studies done. ``jobs`` > 1 runs that many
    studies at once in worker processes: each study depends on its seed alone, so the
    results are the same."""
    study = functools.partial(
        run_study,
        sessions,
        minutes,
        proactivity,
        settings=settings,
        chooser=chooser,
        population=population,
        calibration=calibration,
        repeat=repeat,
    )
    results: list[StudyResult] = []
    if jobs <= 1:
        for seed in seeds:
            results.append(study(seed))
            if progress is not None:
                progress(len(results))
        return results
    with ProcessPoolExecutor(jobs) as pool:
        for result in pool.map(study, seeds):
            results.append(result)
            if progress is not None:
                progress(len(results))
    return results


def per_study(results: Sequence[StudyResult]) -> dict[str, list[float]]:
    """Per metric (Table 4's, the outcomes and the failure totals), one value per study."""
    out: dict[str, list[float]] = {key: [] for key in (*METRICS, *OUTCOMES, *FAILURES)}
    for result in results:
        means = rows(result.sessions)
        for key in (*METRICS, *OUTCOMES):
            out[key].append(means[key][0])
        for key, count in failures(result.sessions).items():
            out[key].append(float(count))
    return out


def estimate(values: Sequence[float], paper: float | None) -> Estimate:
    """The mean of ``values`` with its t interval and the 95 % range of single values."""
    from scipy import stats

    data = list(values)
    mean = statistics.fmean(data)
    if len(data) > 1:
        half = stats.t.ppf(0.975, len(data) - 1) * statistics.stdev(data) / math.sqrt(len(data))
        ordered = sorted(data)
        studies = (_quantile(ordered, 0.025), _quantile(ordered, 0.975))
    else:
        half, studies = 0.0, (mean, mean)
    return Estimate(mean, (mean - half, mean + half), studies, paper)


def summary(results: Sequence[StudyResult]) -> dict[str, Estimate]:
    """Each metric over the studies, beside the paper's value where it has one."""
    values = per_study(results)
    papers: dict[str, float] = {k: v[0] for k, v in PAPER.items()} | {
        k: float(v) for k, v in PAPER_FAILURES.items()
    }
    return {key: estimate(series, papers.get(key)) for key, series in values.items()}


def role(key: str) -> str:
    """Whether a Table 4 row is an input, partly an input or a prediction."""
    if key in INPUT_METRICS:
        return "input"
    if key in PARTLY_INPUT:
        return "partly input"
    return "prediction" if key in PAPER or key in PAPER_FAILURES else "outcome"


def table(estimates: dict[str, Estimate], seeds: Sequence[int]) -> str:
    """The prediction beside the paper, one row per metric."""
    label = f"seeds {seeds[0]}-{seeds[-1]}" if len(seeds) > 1 else f"seed {seeds[0]}"
    lines = [
        f"Table 4 predicted over {len(seeds)} studies ({label}); failures are totals a study",
        f"{'Metric':<38} {'role':<13} {'mean':>8} {'95 % CI':>17} "
        f"{'95 % of studies':>17} {'paper':>8}",
        "-" * 107,
    ]
    for key, e in estimates.items():
        paper = "" if e.paper is None else f"{e.paper:g}"
        inside = (
            "" if e.paper is None else ("" if e.studies[0] <= e.paper <= e.studies[1] else " !")
        )
        name = LABELS.get(key, key.replace("_", " ").capitalize())
        lines.append(
            f"{name:<38} {role(key):<13} {e.mean:8.2f} [{e.ci[0]:7.2f}, {e.ci[1]:7.2f}] "
            f"[{e.studies[0]:7.2f}, {e.studies[1]:7.2f}] {paper:>8}{inside}"
        )
    lines.append("! the paper's value is outside the range of 95 % of simulated studies")
    return "\n".join(lines)


@dataclass(frozen=True)
class Difference:
    """B - A on one metric, paired on seeds and participants."""

    a: float
    b: float
    diff: float
    ci: tuple[float, float]


def paired(a: Sequence[StudyResult], b: Sequence[StudyResult]) -> dict[str, Difference]:
    """Per metric, B - A with a bootstrap 95 % interval (over seeds, or over session
    pairs with one seed)."""
    out: dict[str, Difference] = {}
    for key in (*METRICS, *OUTCOMES):
        units: list[float] = []
        xs_all: list[float] = []
        ys_all: list[float] = []
        for ra, rb in zip(a, b, strict=True):
            pairs = [
                (x, y)
                for x, y in zip(ra.metric_values()[key], rb.metric_values()[key], strict=True)
                if x is not None and y is not None
            ]
            xs_all += [x for x, _ in pairs]
            ys_all += [y for _, y in pairs]
            if len(a) > 1 and pairs:
                units.append(statistics.fmean(y - x for x, y in pairs))
        if len(a) == 1:
            units = [y - x for x, y in zip(xs_all, ys_all, strict=True)]
        mean_a = statistics.fmean(xs_all) if xs_all else math.nan
        mean_b = statistics.fmean(ys_all) if ys_all else math.nan
        diff = statistics.fmean(units) if units else math.nan
        out[key] = Difference(mean_a, mean_b, diff, bootstrap_ci(units, seed=0))
    return out


def paired_by_visit(
    a: Sequence[StudyResult], b: Sequence[StudyResult]
) -> list[dict[str, Difference]]:
    """:func:`paired` of each visit apart (1..repeat): what each side gives a person at
    her first visit, her second..."""
    repeat = a[0].repeat if a else 1
    return [
        paired([r.of_visit(visit) for r in a], [r.of_visit(visit) for r in b])
        for visit in range(1, repeat + 1)
    ]


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
    if len(data) < 3:
        return (float(data.min()), float(data.max()))
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


def _quantile(ordered: list[float], q: float) -> float:
    position = q * (len(ordered) - 1)
    low = math.floor(position)
    high = min(low + 1, len(ordered) - 1)
    return ordered[low] + (ordered[high] - ordered[low]) * (position - low)


def _round(value: float) -> float | None:
    return round(value, 4) if math.isfinite(value) else None
