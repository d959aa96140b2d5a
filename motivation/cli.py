"""``dms motivation plot|show``: see what a ``[motivation]`` table does before deploying it.

Both read the ``[motivation]`` table (and ``timezone``) of a daemon TOML file, the same
table ``dms run`` reads, through ``motivation.load_config``. Anything wrong with the
file, a value or a flag is a ``ConfigError`` (one ``dms: ...`` line from ``dms.cli``).
The command line is an entry point, so ``plot`` reads the system clock for its default
start (today, 08:00 local: a robot switched on in the morning).
"""

from __future__ import annotations

import json
import zoneinfo
from collections.abc import Callable
from dataclasses import dataclass
from datetime import datetime, time, tzinfo
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import typer

from dms.kernel.errors import ConfigError
from dms.kernel.tomlfile import read_toml
from motivation.config import MotivationConfig, MotivationConfigError, load_config

app = typer.Typer(no_args_is_help=True)

CatalogueLoader = Callable[[Path | None, Path | None], None]
"""Put in force the activities of a daemon's TOML file's behaviors folder (second
argument), as ``dms run`` does, so a drive may name a declared activity."""

_catalogue_loader: list[CatalogueLoader] = []


def use_catalogue_loader(loader: CatalogueLoader) -> None:
    """Wire what loads the declared activities (the composition root; this package
    cannot read behavior files)."""
    _catalogue_loader[:] = [loader]


MAX_HOURS = 60 * 24.0
"""Longest plot: 60 days (about 2 s of simulation and a very dense picture)."""
DEFAULT_START = time(8, 0)

ConfigOption = Annotated[
    Path | None,
    typer.Option("--config", help="Daemon TOML file; its [motivation] table and timezone."),
]


@dataclass(frozen=True)
class DaemonFile:
    """What these commands take from a daemon TOML file."""

    motivation: MotivationConfig
    timezone: str | None


def read_daemon_file(path: Path | None) -> DaemonFile:
    """The validated ``[motivation]`` table and the ``timezone`` of ``path`` (defaults if None)."""
    if path is None:
        return DaemonFile(load_config({}), None)
    data = read_toml(path)
    table: Any = data.get("motivation", {})
    if not isinstance(table, dict):
        raise ConfigError(f"{path}: motivation: must be a table")
    timezone = data.get("timezone")
    if timezone is not None and not isinstance(timezone, str):
        raise ConfigError(f"{path}: timezone: must be a string such as 'Europe/Madrid'")
    if _catalogue_loader:  # a drive may name an activity the file's behaviors declare
        _catalogue_loader[0](None, path)
    try:
        return DaemonFile(load_config(table), timezone)
    except MotivationConfigError as error:
        raise ConfigError(f"{path}: {error}") from None


def zone_named(name: str, where: str = "--timezone") -> tzinfo:
    """The IANA time zone ``name``; ConfigError naming ``where`` it came from if there is none."""
    try:
        return zoneinfo.ZoneInfo(name)
    except (zoneinfo.ZoneInfoNotFoundError, ValueError):
        raise ConfigError(f"{where}: unknown time zone {name!r}") from None


def start_at(text: str | None, zone: tzinfo) -> datetime:
    """``--start`` as an aware datetime; a naive one is local time in ``zone``."""
    if text is None:
        return datetime.combine(datetime.now(zone).date(), DEFAULT_START, zone)
    try:
        start = datetime.fromisoformat(text)
    except ValueError:
        raise ConfigError(f"--start: not an ISO date and time: {text!r}") from None
    return start if start.tzinfo is not None else start.replace(tzinfo=zone)


def _checked_out(out: Path) -> Path:
    from matplotlib.backend_bases import FigureCanvasBase

    formats = FigureCanvasBase.get_supported_filetypes()
    suffix = out.suffix.removeprefix(".").lower()
    if suffix not in formats:
        raise ConfigError(f"--out: {out}: the name must end in one of .{', .'.join(formats)}")
    if not out.parent.is_dir():
        raise ConfigError(f"--out: {out.parent} is not a directory")
    return out


@app.command("plot")
def plot_command(
    out: Annotated[Path, typer.Option("--out", help="Image file to write (.png, .svg, .pdf).")],
    hours: Annotated[float, typer.Option("--hours", help="Simulated hours.")] = 48.0,
    config: ConfigOption = None,
    start: Annotated[
        str | None,
        typer.Option("--start", help="ISO start; naive means local (default: today 08:00)."),
    ] = None,
    timezone: Annotated[
        str | None,
        typer.Option("--timezone", help="IANA zone of the rhythm (default: the file's, or UTC)."),
    ] = None,
) -> None:
    """Draw drives, motivations, the dominant motivation and wellbeing with nobody there."""
    from motivation.model import MotivationModel
    from motivation.plot import draw, idle_run

    if not 0 < hours <= MAX_HOURS:
        raise ConfigError(f"--hours: must be in (0, {MAX_HOURS:g}] (got {hours:g})")
    daemon = read_daemon_file(config)
    if timezone is None and daemon.timezone is not None:
        zone = zone_named(daemon.timezone, f"{config}: timezone")
    else:
        zone = zone_named(timezone or "UTC")
    begin = start_at(start, zone)
    out = _checked_out(out)
    model = MotivationModel(daemon.motivation, zone)
    run = idle_run(model, begin, hours)
    title = f"{hours:g} h with no user from {begin.astimezone(zone):%Y-%m-%d %H:%M} ({zone})"
    try:
        draw(model, run, begin, out, title)
    except OSError as error:
        raise ConfigError(f"--out: cannot write {out}: {error.strerror or error}") from None
    behaviors = np.array([*model.table.behaviors, model.config.idle_behavior])[run.dominant]
    share = float(np.mean(behaviors == "sleep")) if len(behaviors) else 0.0
    typer.echo(
        f"wrote {out}: {run.switches} behavior changes, asleep {share:.0%} of the time, "
        f"final wellbeing {model.wellbeing(run.final.drives):.1f}"
    )


@app.command("show")
def show_command(config: ConfigOption = None) -> None:
    """Print the effective [motivation] configuration (defaults merged in) as JSON."""
    daemon = read_daemon_file(config)
    typer.echo(json.dumps(daemon.motivation.model_dump(mode="json"), indent=2))
