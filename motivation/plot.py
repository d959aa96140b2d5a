"""A picture of the idle robot's days, for a designer tuning ``[motivation]``.

``idle_run`` simulates the robot with nobody there (the running behavior follows the
dominant motivation, as the daemon's step 4 does); ``draw`` writes drives,
motivations, the dominant motivation and wellbeing on one time axis in the robot's
local time. Matplotlib draws on an Agg canvas of its own: no pyplot, no GUI, no global
state, so it also works in a daemon or a test process.
"""

from __future__ import annotations

from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import TYPE_CHECKING

from motivation.dynamics import FloatArray
from motivation.model import NO_DOMINANT, MotivationModel
from motivation.trajectory import Run, simulate

if TYPE_CHECKING:
    from matplotlib.axes import Axes

MAX_SAMPLES = 5000
"""About this many samples per curve, whatever the length of the run."""
COLORS = ("#4c72b0", "#dd8452", "#55a868", "#c44e52", "#8172b3", "#937860", "#da8bc3")


def idle_run(model: MotivationModel, start: datetime, hours: float, tick_s: float = 0.5) -> Run:
    """``hours`` with no user from the configured initial state, sampled for a plot."""
    ticks = max(1, int(hours * 3600 / tick_s))
    every = max(1, ticks // MAX_SAMPLES)
    state = model.initial_state(start)
    return simulate(
        model,
        state,
        start,
        hours * 3600,
        model.no_stimuli(),
        follow=True,
        tick_s=tick_s,
        every=every,
    )


def draw(model: MotivationModel, run: Run, start: datetime, out: Path, title: str) -> Path:
    """Write the four panels of ``run`` to ``out`` (the format from its suffix)."""
    from matplotlib import ticker
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(12, 9), layout="constrained")
    FigureCanvasAgg(figure)
    drives_ax, motivations_ax, dominant_ax, wellbeing_ax = figure.subplots(
        4, 1, sharex=True, height_ratios=(3, 3, 1.4, 1.6)
    )
    moments = run.seconds / 3600.0  # hours from the start; labelled in local time below
    names = model.names
    colors = [COLORS[i % len(COLORS)] for i in range(len(names))]

    for i, name in enumerate(names):
        drive = model.config.active_drives[name]
        drives_ax.plot(moments, run.drives[:, i], color=colors[i], label=name)
        drives_ax.axhline(drive.threshold, color=colors[i], linestyle="--", linewidth=0.8)
        if drive.release != drive.threshold:
            drives_ax.axhline(drive.release, color=colors[i], linestyle=":", linewidth=0.8)
        motivations_ax.plot(
            moments, run.motivations[:, i], color=colors[i], label=f"{name} → {drive.behavior}"
        )
    drives_ax.set_ylabel("drive D (deficit)")
    drives_ax.set_ylim(-2, 102)
    drives_ax.legend(loc="upper left", ncols=len(names), fontsize="small")
    drives_ax.set_title("dashed: threshold, dotted: satiation", fontsize="small", loc="right")
    motivations_ax.set_ylabel("motivation M")
    motivations_ax.legend(loc="upper left", ncols=len(names), fontsize="small")

    _dominant_band(dominant_ax, model, run, moments, colors)

    wellbeing_ax.plot(moments, run.wellbeing, color="black")
    wellbeing_ax.set_ylabel("wellbeing")
    wellbeing_ax.set_ylim(0, 100)
    marks = _local_marks(start, float(run.seconds[-1]) if len(run.seconds) else 0.0, model)
    wellbeing_ax.xaxis.set_major_locator(ticker.FixedLocator(marks))
    wellbeing_ax.xaxis.set_major_formatter(
        ticker.FuncFormatter(lambda x, _: _local_label(start, x, model))
    )
    wellbeing_ax.set_xlabel(f"local time ({model.zone})")
    for ax in (drives_ax, motivations_ax, dominant_ax, wellbeing_ax):
        ax.grid(True, alpha=0.3)
    figure.suptitle(title)
    figure.savefig(out, dpi=100)
    return out


def _local_marks(start: datetime, seconds: float, model: MotivationModel) -> list[float]:
    """Hours from ``start`` of each local 00:00, 06:00, 12:00, 18:00 (fewer on long runs)."""
    step = 6 if seconds <= 2 * 86_400 else 12 if seconds <= 5 * 86_400 else 24
    start = start.astimezone(UTC)  # elapsed time: aware datetimes subtract in UTC only so
    local = start.astimezone(model.zone)
    mark = local.replace(minute=0, second=0, microsecond=0, hour=local.hour - local.hour % step)
    marks: list[float] = []
    while (hours := (mark.astimezone(UTC) - start).total_seconds() / 3600.0) <= seconds / 3600:
        if hours >= 0:
            marks.append(hours)
        # by wall clock: the next mark is 06:00 local even across a daylight-saving change
        naive = mark.replace(tzinfo=None) + timedelta(hours=step)
        mark = naive.replace(tzinfo=model.zone)
    return marks


def _local_label(start: datetime, hours: float, model: MotivationModel) -> str:
    return f"{(start.astimezone(UTC) + timedelta(hours=hours)).astimezone(model.zone):%a %H:%M}"


def _dominant_band(
    ax: Axes, model: MotivationModel, run: Run, moments: FloatArray, colors: list[str]
) -> None:
    """One row per drive (and one for none), filled where that drive dominates."""
    rows = [*range(len(model.names)), NO_DOMINANT]
    labels = [f"{n} → {b}" for n, b in zip(model.names, model.table.behaviors, strict=True)]
    labels.append(f"none → {model.config.idle_behavior}")
    if len(moments) > 1:
        for row, index in enumerate(rows):
            color = colors[index] if index != NO_DOMINANT else "#bbbbbb"
            ax.fill_between(
                moments,
                row - 0.4,
                row + 0.4,
                where=run.dominant == index,
                step="post",
                color=color,
                linewidth=0,
            )
    ax.set_yticks(range(len(rows)), labels, fontsize="small")
    ax.set_ylim(-0.6, len(rows) - 0.4)
    ax.invert_yaxis()
    ax.set_ylabel("dominant")
