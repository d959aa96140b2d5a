"""``dms agenda list|add|remove|missed``: the agenda from the command line.

These commands open the daemon's database directly (``--db`` or ``DMS_DB``, default
the daemon's file), and never create one: a SQLite file that does not exist is refused.
The command line is an entry point, so it reads the system clock for ``now``. A running
daemon loads a user's items again when it next perceives that user; to change the agenda
of a running daemon at once, use its Zenoh queryable (docs/agenda.md).

``add --event`` takes the activities the daemon knows: the shipped ones and those its
behaviors folder declares (``--behaviors``, else the folder of ``--config`` and the
``DMS_*`` variables, as ``dms run`` reads them). This package cannot read behavior
files; the composition root wires the loader that does (:func:`use_catalogue_loader`).
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from datetime import datetime
from pathlib import Path
from typing import Annotated, Any, Literal

import typer

from agenda.errors import AgendaError
from agenda.items import ItemSpec, UpcomingItem
from agenda.service import Agenda
from dms.kernel.cli_options import DbOption, JsonOption
from dms.kernel.clock import RealClock
from memory.cli import existing_url, print_table

app = typer.Typer(no_args_is_help=True)

CatalogueLoader = Callable[[Path | None, Path | None], None]
"""Put in force the catalogue of a behaviors folder (first) or a configuration file's
folder (second); raises a DmsError with one line when either is wrong."""

_catalogue_loader: list[CatalogueLoader] = []


def use_catalogue_loader(loader: CatalogueLoader) -> None:
    """Wire what loads the declared activities (the composition root, at import)."""
    _catalogue_loader[:] = [loader]


def _url(db: str | None) -> str:
    return existing_url(db)


def _user_check(url: str) -> tuple[Callable[[str], bool] | None, Callable[[], None]]:
    """The profile store's "does this user exist", when the memory package has one."""
    import memory

    store_class: Any = getattr(memory, "ProfileStore", None)
    if store_class is None:
        return None, lambda: None
    store = store_class(url)

    def exists(user_id: str) -> bool:
        try:
            return store.get(user_id) is not None
        except KeyError:  # ProfileNotFound
            return False

    return exists, getattr(store, "close", lambda: None)


@contextmanager
def _agenda(db: str | None, check_users: bool = False) -> Iterator[Agenda]:
    url = _url(db)
    exists, close_store = _user_check(url) if check_users else (None, lambda: None)
    try:
        agenda = Agenda.open(url, user_exists=exists)
        try:
            yield agenda
        finally:
            agenda.close()
    finally:
        close_store()


def _row(item: UpcomingItem) -> list[str]:
    what = item.text if item.kind == "reminder" else item.activity
    local = item.to_json()["next_fire_local"][:16].replace("T", " ")
    flag = " (due, waiting)" if item.waiting else ""
    return [
        str(item.item_id),
        item.user_id,
        item.kind,
        item.priority,
        local,
        item.tz,
        item.schedule,
        f"{what}{flag}",
    ]


@app.command("list")
def list_command(
    user: Annotated[str | None, typer.Option(help="Only this user's items.")] = None,
    db: DbOption = None,
    limit: Annotated[int, typer.Option(min=1, help="At most this many items.")] = 100,
    as_json: JsonOption = False,
) -> None:
    """List upcoming items with their next fire time, soonest first."""
    with _agenda(db) as agenda:
        items = agenda.upcoming(user, RealClock().now(), limit)
    if as_json:
        typer.echo(json.dumps({"items": [item.to_json() for item in items]}, ensure_ascii=False))
        return
    if not items:
        typer.echo("no upcoming agenda items")
        return
    header = ["id", "user", "kind", "priority", "next (local)", "tz", "schedule", "what"]
    print_table(None, header, [_row(item) for item in items])


@app.command("add")
def add_command(
    user: Annotated[str, typer.Option(help="The user the item belongs to.")],
    reminder: Annotated[str | None, typer.Option(help="A reminder: the text to say.")] = None,
    event: Annotated[str | None, typer.Option(help="An event: the activity to run.")] = None,
    at: Annotated[
        str | None, typer.Option(help="Once, at this ISO date-time (wall time in --tz).")
    ] = None,
    cron: Annotated[
        str | None, typer.Option(help='A crontab expression, e.g. "0 10 * * MON".')
    ] = None,
    every: Annotated[int | None, typer.Option(help="Every this many seconds.")] = None,
    tz: Annotated[str, typer.Option(help="IANA time zone, e.g. Europe/Madrid.")] = "UTC",
    priority: Annotated[
        Literal["normal", "high"],
        typer.Option(help="high cancels the running activity; normal waits for its end."),
    ] = "normal",
    lead: Annotated[int, typer.Option(help="Announce this many seconds early.")] = 0,
    grace: Annotated[int, typer.Option(help="Wait this many seconds for the user.")] = 600,
    behaviors: Annotated[
        Path | None,
        typer.Option(
            "--behaviors",
            help="The daemon's behaviors folder: its declared activities are events too.",
            show_default="the folder of --config",
        ),
    ] = None,
    config: Annotated[
        Path | None,
        typer.Option("--config", help="The daemon's TOML file (as dms run --config)."),
    ] = None,
    db: DbOption = None,
    as_json: JsonOption = False,
) -> None:
    """Add a reminder (--reminder TEXT) or an event (--event ACTIVITY)."""
    if (reminder is None) == (event is None):
        raise AgendaError("give exactly one of --reminder TEXT or --event ACTIVITY")
    if event is not None and _catalogue_loader:
        _catalogue_loader[0](behaviors, config)
    when: datetime | None = None
    if at is not None:
        try:
            when = datetime.fromisoformat(at)
        except ValueError:
            raise AgendaError(
                f"--at: {at!r} is not an ISO date-time like 2026-11-23T16:45"
            ) from None
    spec = ItemSpec.from_data(
        {
            "user_id": user,
            "kind": "reminder" if reminder is not None else "event",
            "text": reminder,
            "activity": event,
            "at": when,
            "cron": cron,
            "every": every,
            "tz": tz,
            "priority": priority,
            "lead_s": lead,
            "grace_s": grace,
        }
    )
    with _agenda(db, check_users=True) as agenda:
        item = agenda.add(spec, RealClock().now())
    if as_json:
        typer.echo(json.dumps({"item": item.to_json()}, ensure_ascii=False))
        return
    assert item.next_fire is not None
    typer.echo(f"added agenda item {item.item_id}: next at {item.next_fire.isoformat()}")


@app.command("remove")
def remove_command(
    item_id: Annotated[int, typer.Argument(help="The id shown by `dms agenda list`.")],
    db: DbOption = None,
) -> None:
    """Remove an item (its log of deliveries and misses stays)."""
    with _agenda(db) as agenda:
        agenda.remove(item_id)
    typer.echo(f"removed agenda item {item_id}")


@app.command("missed")
def missed_command(
    user: Annotated[str | None, typer.Option(help="Only this user's misses.")] = None,
    db: DbOption = None,
    as_json: JsonOption = False,
) -> None:
    """Show what was missed: the user was away, or the daemon was down, past the grace time."""
    with _agenda(db) as agenda:
        missed = agenda.missed_log(user)
    if as_json:
        typer.echo(json.dumps({"missed": [m.to_json() for m in missed]}, ensure_ascii=False))
        return
    if not missed:
        typer.echo("nothing missed")
        return
    rows = [
        [
            str(m.item_id),
            m.user_id,
            m.fire_time.isoformat(),
            "1" if m.count == 1 else f"{m.count} until {m.last_fire_time.isoformat()}",
            m.what,
            m.reason,
        ]
        for m in missed
    ]
    print_table(None, ["id", "user", "time", "times", "what", "why"], rows)
