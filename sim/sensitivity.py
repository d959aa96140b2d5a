"""``dms sim sensitivity``: which Table 4 metric moves with which participant input.

Each participant input of :mod:`sim.calibration` (:data:`~sim.calibration.PARTICIPANT_INPUTS`)
is moved by ±``change`` (50 % by default), one at a time, and the study is run on the
same seeds as the unmoved baseline; for each metric the change of its mean over the
seeds is recorded. ``sensitivity.csv`` has one row per input, direction and metric;
``sensitivity.png`` is a tornado chart per metric (the inputs sorted by their effect).
"""

from __future__ import annotations

import csv
import statistics
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from sim.calibration import DEFAULT
from sim.prediction import per_study, run_seeds
from sim.study import study_settings
from sim.table4 import LABELS, METRICS, OUTCOMES

SWEPT_METRICS: tuple[str, ...] = (*METRICS, *OUTCOMES)


@dataclass
class Sensitivity:
    """The baseline means and, per input and direction, the moved means."""

    seeds: list[int]
    change: float
    baseline: dict[str, float]
    moved: dict[tuple[str, str], dict[str, float]] = field(default_factory=dict)
    """(input, "low" or "high") -> metric -> mean over the seeds."""

    def effect(self, name: str, direction: str, metric: str) -> float:
        """The metric's mean with the input moved, minus the baseline's."""
        return self.moved[(name, direction)][metric] - self.baseline[metric]

    def inputs(self) -> list[str]:
        return list(dict.fromkeys(name for name, _ in self.moved))

    def driver(self, metric: str) -> str:
        """The input that moves ``metric`` most (largest low-to-high swing)."""
        return max(
            self.inputs(),
            key=lambda n: abs(self.effect(n, "high", metric) - self.effect(n, "low", metric)),
        )

    def to_json(self) -> dict[str, Any]:
        return {
            "seeds": self.seeds,
            "change": self.change,
            "baseline": {k: round(v, 4) for k, v in self.baseline.items()},
            "effects": {
                name: {
                    metric: [
                        round(self.effect(name, "low", metric), 4),
                        round(self.effect(name, "high", metric), 4),
                    ]
                    for metric in SWEPT_METRICS
                }
                for name in self.inputs()
            },
            "drivers": {metric: self.driver(metric) for metric in SWEPT_METRICS},
        }

    def text(self) -> str:
        lines = [
            f"Each input moved by ±{self.change:.0%} (seeds {self.seeds[0]}-{self.seeds[-1]}); "
            "per metric, the input that moves it most:",
        ]
        for metric in SWEPT_METRICS:
            name = self.driver(metric)
            low, high = self.effect(name, "low", metric), self.effect(name, "high", metric)
            lines.append(
                f"  {LABELS[metric]:<38} {self.baseline[metric]:9.2f}  {name:<17} "
                f"-{self.change:.0%}: {low:+.2f}  +{self.change:.0%}: {high:+.2f}"
            )
        return "\n".join(lines)


def _means(seeds: Sequence[int], sessions: int, minutes: float, **kwargs: Any) -> dict[str, float]:
    values = per_study(run_seeds(seeds, sessions, minutes, settings=study_settings(), **kwargs))
    return {key: statistics.fmean(values[key]) for key in SWEPT_METRICS}


def sweep(
    names: Sequence[str],
    seeds: Sequence[int],
    sessions: int = 30,
    minutes: float = 30.0,
    change: float = 0.5,
    progress: Callable[[int], None] | None = None,
) -> Sensitivity:
    """The baseline and each input in ``names`` moved down and up by ``change``."""
    done = 0

    def step() -> None:
        nonlocal done
        done += len(seeds)
        if progress is not None:
            progress(done)

    result = Sensitivity(list(seeds), change, _means(seeds, sessions, minutes))
    step()
    for name in names:
        for direction, factor in (("low", 1.0 - change), ("high", 1.0 + change)):
            calibration = DEFAULT.scaled(name, factor)
            result.moved[(name, direction)] = _means(
                seeds, sessions, minutes, calibration=calibration
            )
            step()
    return result


def write_csv(path: Path, result: Sensitivity) -> Path:
    """One row per input, direction and metric: the means and the change."""
    with path.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(["input", "direction", "factor", "metric", "baseline", "moved", "effect"])
        for (name, direction), means in result.moved.items():
            factor = 1.0 - result.change if direction == "low" else 1.0 + result.change
            for metric in SWEPT_METRICS:
                writer.writerow(
                    [
                        name,
                        direction,
                        round(factor, 3),
                        metric,
                        round(result.baseline[metric], 4),
                        round(means[metric], 4),
                        round(result.effect(name, direction, metric), 4),
                    ]
                )
    return path


def write_tornado(path: Path, result: Sensitivity) -> Path:
    """A tornado chart per metric: each input's effect down (left bar) and up (right)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    metrics = list(SWEPT_METRICS)
    cols = 3
    rows = (len(metrics) + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(5.2 * cols, 3.2 * rows))
    for ax, metric in zip(axes.flat, metrics, strict=False):
        names = sorted(
            result.inputs(),
            key=lambda n: abs(result.effect(n, "high", metric) - result.effect(n, "low", metric)),
        )
        lows = [result.effect(n, "low", metric) for n in names]
        highs = [result.effect(n, "high", metric) for n in names]
        ax.barh(names, lows, color="#4C72B0", label=f"-{result.change:.0%}")
        ax.barh(names, highs, color="#DD8452", label=f"+{result.change:.0%}", alpha=0.8)
        ax.axvline(0.0, color="black", linewidth=0.8)
        ax.set_title(f"{LABELS[metric]} ({result.baseline[metric]:.2f})", fontsize=9)
        ax.tick_params(labelsize=7)
    for ax in list(axes.flat)[len(metrics) :]:
        ax.axis("off")
    axes.flat[0].legend(fontsize=7)
    fig.suptitle("Change of each metric's mean with each participant input moved", fontsize=11)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
