"""``dms sim sensitivity``: which Table 4 metric moves with which input of the study.

Each input is moved by ±``change`` (50 % by default), one at a time, and the study is
run on the same seeds as the unmoved baseline; for each metric the change of its mean
over the seeds is recorded. The inputs are the participants' habits
(:data:`~sim.calibration.PARTICIPANT_INPUTS`), the robot's, the protocol's and the
content's inputs of :mod:`sim.calibration` (:data:`~sim.calibration.SETTING_INPUTS`), and
the controller's settings a designer chooses (:data:`CONTROLLER_INPUTS`). Each metric's
noise floor is the half-width of the 95 % interval of its baseline mean over the seeds:
an effect within it is not told apart from the seeds' own spread, and the input that
moves a metric most is named only when its swing is above it. ``sensitivity.csv`` has
one row per input, direction and metric; ``sensitivity.png`` is a tornado chart per
metric (the inputs sorted by their effect).
"""

from __future__ import annotations

import csv
import math
import statistics
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from dms.config import Settings
from sim.baselines import ChooserName
from sim.calibration import DEFAULT, INPUTS, PARTICIPANT_INPUTS, SETTING_INPUTS
from sim.population import Population
from sim.prediction import per_study, run_seeds
from sim.study import study_settings
from sim.table4 import LABELS, METRICS, OUTCOMES

SWEPT_METRICS: tuple[str, ...] = (*METRICS, *OUTCOMES)
CONTROLLER_INPUTS: tuple[str, ...] = (
    "controller.menu_timeout_s",
    "controller.feedback_probability",
    "controller.session_questions",
)
"""Settings of ``[controller]`` a designer chooses, moved as the other inputs."""
SWEEPABLE: tuple[str, ...] = (*PARTICIPANT_INPUTS, *SETTING_INPUTS, *CONTROLLER_INPUTS)
"""Every input ``dms sim sensitivity`` can move (``--only`` names one of these)."""
NO_DRIVER = "(none above the noise)"


@dataclass
class Sensitivity:
    """The baseline means, their noise floors and, per input and direction, the moved means."""

    seeds: list[int]
    change: float
    baseline: dict[str, float]
    noise: dict[str, float] = field(default_factory=dict)
    """Per metric, the half-width of the 95 % interval of the baseline's mean over the
    seeds (0 with one seed: then no effect can be told from noise, say so)."""
    moved: dict[tuple[str, str], dict[str, float]] = field(default_factory=dict)
    """(input, "low" or "high") -> metric -> mean over the seeds."""

    def effect(self, name: str, direction: str, metric: str) -> float:
        """The metric's mean with the input moved, minus the baseline's."""
        return self.moved[(name, direction)][metric] - self.baseline[metric]

    def inputs(self) -> list[str]:
        return list(dict.fromkeys(name for name, _ in self.moved))

    def swing(self, name: str, metric: str) -> float:
        return abs(self.effect(name, "high", metric) - self.effect(name, "low", metric))

    def driver(self, metric: str) -> str:
        """The input that moves ``metric`` most (largest low-to-high swing), when that
        swing is above the metric's noise floor; :data:`NO_DRIVER` otherwise."""
        best = max(self.inputs(), key=lambda n: self.swing(n, metric))
        return best if self.swing(best, metric) > self.noise.get(metric, 0.0) else NO_DRIVER

    def to_json(self) -> dict[str, Any]:
        return {
            "seeds": self.seeds,
            "change": self.change,
            "baseline": {k: round(v, 4) for k, v in self.baseline.items()},
            "noise_floor": {k: round(v, 4) for k, v in self.noise.items()},
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
            "per metric, its noise floor and the input that moves it most:",
        ]
        for metric in SWEPT_METRICS:
            name = self.driver(metric)
            floor = self.noise.get(metric, 0.0)
            head = f"  {LABELS[metric]:<38} {self.baseline[metric]:9.2f} ±{floor:<7.2f}"
            if name == NO_DRIVER:
                lines.append(f"{head} {name}")
                continue
            low, high = self.effect(name, "low", metric), self.effect(name, "high", metric)
            lines.append(
                f"{head} {name:<32} -{self.change:.0%}: {low:+.2f}  +{self.change:.0%}: {high:+.2f}"
            )
        if len(self.seeds) < 2:
            lines.append("one seed: no noise floor, every effect may be the seeds' own spread")
        return "\n".join(lines)


def _means(
    seeds: Sequence[int], sessions: int, minutes: float, **kwargs: Any
) -> tuple[dict[str, float], dict[str, float]]:
    """Per metric, the mean over the seeds and the half-width of its 95 % interval."""
    from scipy import stats

    values = per_study(run_seeds(seeds, sessions, minutes, **kwargs))
    means = {key: statistics.fmean(values[key]) for key in SWEPT_METRICS}
    noise = {}
    for key in SWEPT_METRICS:
        series = values[key]
        noise[key] = (
            float(stats.t.ppf(0.975, len(series) - 1))
            * statistics.stdev(series)
            / math.sqrt(len(series))
            if len(series) > 1
            else 0.0
        )
    return means, noise


def moved_settings(name: str, factor: float) -> Settings:
    """The study's settings with the controller setting ``controller.X`` times ``factor``
    (a whole number stays whole, a probability at most 1)."""
    settings = study_settings()
    field_name = name.removeprefix("controller.")
    value = getattr(settings.controller, field_name)
    moved: float = value * factor
    if isinstance(value, int):
        moved = round(moved)
    elif field_name.endswith("probability"):
        moved = min(1.0, moved)
    controller = settings.controller.model_copy(update={field_name: moved})
    return settings.model_copy(update={"controller": controller})


def sweep(
    names: Sequence[str],
    seeds: Sequence[int],
    sessions: int = 30,
    minutes: float = 30.0,
    change: float = 0.5,
    progress: Callable[[int], None] | None = None,
    *,
    chooser: ChooserName = "dms",
    population: Population = "paper",
    jobs: int = 1,
) -> Sensitivity:
    """The baseline and each input in ``names`` (of :data:`SWEEPABLE`) moved down and up
    by ``change``, with ``chooser`` making the robot's choices for ``population``; ``jobs``
    studies run at once."""
    done = 0

    def step() -> None:
        nonlocal done
        done += len(seeds)
        if progress is not None:
            progress(done)

    common: dict[str, Any] = {"chooser": chooser, "population": population, "jobs": jobs}
    baseline, noise = _means(seeds, sessions, minutes, settings=study_settings(), **common)
    result = Sensitivity(list(seeds), change, baseline, noise)
    step()
    for name in names:
        for direction, factor in (("low", 1.0 - change), ("high", 1.0 + change)):
            if name in INPUTS:
                moved, _ = _means(
                    seeds,
                    sessions,
                    minutes,
                    settings=study_settings(),
                    calibration=DEFAULT.scaled(name, factor),
                    **common,
                )
            else:
                moved, _ = _means(
                    seeds, sessions, minutes, settings=moved_settings(name, factor), **common
                )
            result.moved[(name, direction)] = moved
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
    fig.suptitle("Change of each metric's mean with each input moved", fontsize=11)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
