"""PNG plots of a long-term run (matplotlib, Agg backend: no display needed)."""

from __future__ import annotations

from pathlib import Path
from typing import Protocol

from sim.errors import SimError


class LongtermRun(Protocol):
    """What the plots read of a long-term run (``sim.longterm.LongtermResult`` has it).

    A protocol, so that ``sim.longterm`` imports this module and not the other way round.
    """

    days: int
    users: list[str]
    activity_seconds: dict[str, float]
    activity_seconds_by_hour: dict[str, dict[str, float]]
    samples: list[tuple[float, dict[str, float], float]]
    spans: list[tuple[str, float, float]]
    presence: list[tuple[int, float, float]]


def write_plots(result: LongtermRun, out: Path) -> list[Path]:
    """Write drives.png, timeline.png and by_hour.png into ``out``; return their paths."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise SimError(f"--out {out}: cannot create: {error.strerror or error}") from None
    paths = [out / "drives.png", out / "timeline.png", out / "by_hour.png"]
    day = 86400.0

    fig, (top, bottom) = plt.subplots(2, 1, figsize=(12, 6), sharex=True)
    times = [t / day for t, _, _ in result.samples]
    names = sorted({name for _, drives, _ in result.samples for name in drives})
    for name in names:
        top.plot(times, [drives.get(name, 0.0) for _, drives, _ in result.samples], label=name)
    top.set_ylabel("drive (deficit)")
    top.set_ylim(0, 100)
    top.legend(loc="upper right")
    bottom.plot(times, [w for _, _, w in result.samples], color="tab:green")
    bottom.set_ylabel("wellbeing")
    bottom.set_xlabel("day")
    bottom.set_ylim(0, 100)
    fig.suptitle(f"Drives and wellbeing over {result.days} days ({', '.join(result.users)})")
    fig.tight_layout()
    _save(fig, paths[0])
    plt.close(fig)

    palette = matplotlib.colormaps["tab20"]
    activities = sorted({name for name, _, _ in result.spans})
    colour = {name: palette(i % 20) for i, name in enumerate(sorted(result.activity_seconds))}
    fig, ax = plt.subplots(figsize=(12, max(3.0, 0.4 * (len(activities) + 1) + 1)))
    for row, name in enumerate(activities):
        bars = [(t0 / day, (t1 - t0) / day) for n, t0, t1 in result.spans if n == name]
        ax.broken_barh(bars, (row - 0.4, 0.8), color=colour.get(name))
    present_row = len(activities)
    for user, t0, t1 in result.presence:
        ax.broken_barh(
            [(t0 / day, (t1 - t0) / day)],
            (present_row - 0.4, 0.8),
            color=palette((2 * user + 1) % 20),
        )
    ax.set_yticks(range(len(activities) + 1), [*activities, "user present"])
    ax.set_xlabel("day")
    ax.set_xlim(0, result.days)
    ax.set_title("Activity timeline")
    fig.tight_layout()
    _save(fig, paths[1])
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(12, 5))
    hours = list(range(24))
    bottom_h = [0.0] * 24
    names_by_time = sorted(result.activity_seconds, key=lambda n: -result.activity_seconds[n])
    for name in names_by_time:
        values = [
            result.activity_seconds_by_hour.get(str(h), {}).get(name, 0.0) / 3600 for h in hours
        ]
        ax.bar(hours, values, bottom=bottom_h, label=name, color=colour.get(name))
        bottom_h = [b + v for b, v in zip(bottom_h, values, strict=True)]
    ax.set_xticks(hours)
    ax.set_xlabel("hour of day")
    ax.set_ylabel("hours over the run")
    ax.set_title("Activity by hour of day")
    ax.legend(loc="center left", bbox_to_anchor=(1.0, 0.5), fontsize="small")
    fig.tight_layout()
    _save(fig, paths[2])
    plt.close(fig)
    return paths


def _save(fig: object, path: Path) -> None:
    try:
        fig.savefig(path, dpi=90)  # type: ignore[attr-defined]
    except OSError as error:
        raise SimError(f"{path}: cannot write: {error.strerror or error}") from None
