"""``dms sessions list|export``: the Table 4 metrics of each real session, and its events.

The daemon stores each session's metrics (``dms.kernel.session_metrics``) when the session
ends; these commands read them back from its database, so that a deployment yields
its own Table 4 beside the paper's and the simulator's (the columns are those of
``dms sim study --out``'s ``sessions.csv``). ``export --events`` prints instead one row
per interaction event (:mod:`memory.interactions`): what ``dms sim fit`` learns the
simulated participants from, and what a researcher loads in pandas or R. They only
read: a database file that does not exist is refused in one line, never created.
"""

from __future__ import annotations

import csv
import io
import json
import statistics
from datetime import UTC, datetime
from typing import Annotated, Any, Literal

import typer

from dms.kernel.cli_options import DbOption
from dms.kernel.session_metrics import METRIC_KEYS
from memory.cli import existing_url
from memory.interactions import COLUMNS as EVENT_COLUMNS
from memory.store import ProfileStore

app = typer.Typer(no_args_is_help=True)

COLUMNS: tuple[str, ...] = ("session", "user", "started", "ended", *METRIC_KEYS)
"""One row per session: these keys in JSON, these columns in CSV."""

SinceOption = Annotated[
    str | None,
    typer.Option("--since", help="Only sessions started on or after this date (ISO, UTC)."),
]


def parse_since(value: str | None) -> datetime | None:
    """``--since``: a date (``2026-11-24``) or a time (``2026-11-24T09:30``); UTC unless
    it says otherwise."""
    if value is None:
        return None
    try:
        since = datetime.fromisoformat(value.strip())
    except ValueError:
        raise typer.BadParameter(
            f"not a date: {value!r} (use YYYY-MM-DD or an ISO time)", param_hint="--since"
        ) from None
    return since if since.tzinfo is not None else since.replace(tzinfo=UTC)


def read_rows(db: str | None, since: str | None) -> list[dict[str, Any]]:
    """One flat row per session (:data:`COLUMNS`), oldest first; metrics absent (an open
    session, or one stored before the daemon measured them) are None."""
    start = parse_since(since)
    store = ProfileStore(existing_url(db))
    try:
        sessions = store.sessions(start)
    finally:
        store.close()
    rows: list[dict[str, Any]] = []
    for item in sessions:
        metrics = item["metrics"] or {}
        row = {key: item[key] for key in ("session", "user", "started", "ended")}
        row.update({key: metrics.get(key) for key in METRIC_KEYS})
        rows.append(row)
    return rows


def read_events(db: str | None, since: str | None) -> list[dict[str, Any]]:
    """One flat row per interaction event (:data:`memory.interactions.COLUMNS`)."""
    start = parse_since(since)
    store = ProfileStore(existing_url(db))
    try:
        return store.interaction_events(start)
    finally:
        store.close()


@app.command("export")
def export_sessions(
    db: DbOption = None,
    since: SinceOption = None,
    fmt: Annotated[Literal["csv", "json"], typer.Option("--format", help="csv or json.")] = "json",
    events: Annotated[
        bool,
        typer.Option(
            "--events",
            help="One row per interaction event (offers, inputs, activities) instead of "
            "one per session (columns: docs/memory.md).",
        ),
    ] = False,
) -> None:
    """Print every session's metrics (or with --events its interaction events) to
    stdout, as CSV or JSON (a list of objects)."""
    rows = read_events(db, since) if events else read_rows(db, since)
    if fmt == "json":
        typer.echo(json.dumps(rows, indent=2))
        return
    out = io.StringIO()
    columns = EVENT_COLUMNS if events else COLUMNS
    writer = csv.DictWriter(out, fieldnames=list(columns), lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: "" if v is None else v for k, v in row.items()})
    typer.echo(out.getvalue(), nl=False)


_SHOWN: tuple[tuple[str, str], ...] = (
    ("duration_s", "min"),
    ("questions_per_session", "questions"),
    ("activities_per_session", "activities"),
    ("activity_load_time_s", "load s"),
    ("activity_time_s", "activity s"),
    ("change_time_s", "change s"),
    ("robot_decisions_per_session", "robot"),
    ("user_selections_per_session", "user"),
    ("cancels_per_session", "cancels"),
    ("failures", "failures"),
)
_FAILURES = ("activity_not_loaded", "speech_recognition_errors", "user_not_answering", "other")


def _value(row: dict[str, Any], key: str) -> float | None:
    if key == "failures":
        values = [row[k] for k in _FAILURES if row[k] is not None]
        return float(sum(values)) if values else None
    value = row[key]
    if value is None:
        return None
    return float(value) / 60.0 if key == "duration_s" else float(value)


def _cell(value: float | None) -> str:
    if value is None:
        return "-"
    return f"{value:.0f}" if value == int(value) and abs(value) < 1e9 else f"{value:.2f}"


def table_lines(rows: list[dict[str, Any]]) -> tuple[list[str], list[list[str]], list[str]]:
    """The list's header, one row per session, and the mean over sessions of each
    column (the deployment's Table 4: sessions without a value are left out)."""
    header = ["session", "user", "started", *(label for _key, label in _SHOWN)]
    body = [
        [str(row["session"]), str(row["user"]), str(row["started"])[:16].replace("T", " ")]
        + [_cell(_value(row, key)) for key, _label in _SHOWN]
        for row in rows
    ]
    means: list[str] = ["mean", f"{len(rows)} sessions", ""]
    for key, _label in _SHOWN:
        values = [v for row in rows if (v := _value(row, key)) is not None]
        means.append(f"{statistics.fmean(values):.2f}" if values else "-")
    return header, body, means


@app.command("list")
def list_sessions(db: DbOption = None, since: SinceOption = None) -> None:
    """Print a table, one row per session, and the mean of each column."""
    header, body, means = table_lines(read_rows(db, since))
    try:
        from rich.console import Console
        from rich.table import Table
    except ImportError:
        widths = [max(len(r[i]) for r in (header, *body, means)) for i in range(len(header))]
        for line in (header, *body, means):
            typer.echo(
                "  ".join(
                    cell.rjust(width) for cell, width in zip(line, widths, strict=True)
                ).rstrip()
            )
        return
    table = Table(title="Sessions (the metrics of the paper's Table 4, measured by the daemon)")
    for index, name in enumerate(header):
        table.add_column(name, justify="left" if index < 3 else "right", no_wrap=True)
    for line in body:
        table.add_row(*line)
    table.add_section()
    table.add_row(*means)
    Console(width=200 if not typer.get_text_stream("stdout").isatty() else None).print(table)
