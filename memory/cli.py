"""``dms users list|add|show|export|erase`` and ``dms db upgrade``.

These commands open the daemon's database directly (``--db`` or ``DMS_DB``, default
the daemon's file). They work while the daemon runs: SQLite is in WAL mode, so a
reader never blocks the daemon and an erase waits at most the busy timeout for its
turn. They never create a database: a SQLite file that does not exist is refused in
one line (only ``dms run`` and ``dms db upgrade`` create one).
"""

from __future__ import annotations

import difflib
import json
import sys
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from datetime import UTC, datetime
from pathlib import Path
from typing import Annotated

import typer
from sqlalchemy import Engine
from sqlalchemy.engine import make_url
from sqlalchemy.exc import ArgumentError, SQLAlchemyError

from dms.kernel.cli_options import DbOption
from memory import migrations
from memory.db import as_url, default_url, make_engine
from memory.errors import ProfileError, one_line
from memory.profile import ALIASES, FIELDS, validate_fields
from memory.schema_history import SchemaHistory
from memory.store import ProfileStore

app = typer.Typer(no_args_is_help=True)

UserArgument = Annotated[str, typer.Argument(help="The user id.")]


def existing_url(db: str | None) -> str:
    """The database URL to read or change; a SQLite file that does not exist is refused
    (a read must not leave an empty database behind, nor answer "nothing" for a typo)."""
    url = as_url(db) if db else default_url()
    try:
        parsed = make_url(url)
    except ArgumentError as error:
        raise ProfileError(f"cannot open database {url!r}: {one_line(error)}") from None
    database = parsed.database
    local = parsed.get_backend_name() == "sqlite" and database and database != ":memory:"
    if local and database and not Path(database).expanduser().exists():
        raise ProfileError(f"no database at {database} (dms run or dms db upgrade creates one)")
    return url


def print_table(title: str | None, header: Sequence[str], rows: Sequence[Sequence[str]]) -> None:
    """A listing as a rich table on stdout (wide, without colour, when it is not a
    terminal, so that a pipe or a file gets every column whole)."""
    from rich.console import Console
    from rich.table import Table

    table = Table(title=title)
    for name in header:
        table.add_column(name, overflow="fold")
    for row in rows:
        table.add_row(*row)
    terminal = sys.stdout.isatty()
    Console(width=None if terminal else 200, no_color=not terminal).print(table)


@contextmanager
def _store(db: str | None) -> Iterator[ProfileStore]:
    store = ProfileStore(existing_url(db))
    try:
        yield store
    finally:
        store.close()


LISTED = ("name", "age", "language", "proactivity", "interaction_style")
"""The profile fields ``dms users list`` shows beside the id."""


@app.command("list")
def list_users(
    db: DbOption = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print the ids as JSON.")] = False,
) -> None:
    """List every stored user: a table of id, name, age, language, proactivity, style."""
    with _store(db) as store:
        ids = store.list_ids()
        profiles = [store.get(user_id) for user_id in ids]
    if as_json:
        typer.echo(json.dumps({"users": ids}))
        return
    rows = []
    for profile in profiles:
        data = profile.model_dump(mode="json")
        rows.append([profile.user_id, *(_shown(data.get(name)) for name in LISTED)])
    print_table(None, ["id", *LISTED], rows)


def _shown(value: object) -> str:
    return "-" if value is None else str(value)


def _literal(raw: str) -> object:
    """A JSON literal when ``raw`` parses as one (``72``, ``true``), else the text itself."""
    try:
        return json.loads(raw)
    except ValueError:
        return raw


def _assignment(flag: str, item: str) -> tuple[str, object]:
    name, sep, raw = item.partition("=")
    if not sep or not name.strip():
        raise ProfileError(f"{flag} {item!r}: expected NAME=VALUE")
    return name.strip(), _literal(raw)


def _known_field(item: str) -> tuple[str, object]:
    """One ``--set NAME=VALUE``: NAME must be a profile field (a typo is not stored)."""
    name, value = _assignment("--set", item)
    if name in FIELDS or name in ALIASES:
        return name, value
    close = difflib.get_close_matches(name, [*FIELDS, *ALIASES], n=1)
    known = f"did you mean {close[0]}?" if close else f"fields: {', '.join(FIELDS)}"
    raise ProfileError(
        f"--set {name}: not a profile field ({known}); a free attribute goes in --extra"
    )


def _free_attribute(item: str) -> tuple[str, object]:
    """One ``--extra NAME=VALUE``: a free attribute, never a profile field's name."""
    name, value = _assignment("--extra", item)
    if name in FIELDS or name in ALIASES:
        raise ProfileError(f"--extra {name}: is a profile field; use --set {name}=VALUE")
    return name, value


@app.command("add")
def add_user(
    user_id: UserArgument,
    fields: Annotated[
        list[str] | None,
        typer.Option(
            "--set",
            help="A profile field, NAME=VALUE (e.g. name=Ann, age=81); fields: "
            + ", ".join(FIELDS)
            + ".",
            show_default=False,
        ),
    ] = None,
    extra: Annotated[
        list[str] | None,
        typer.Option(
            "--extra",
            help="A free attribute the rules may read, NAME=VALUE (e.g. pet=cat).",
            show_default=False,
        ),
    ] = None,
    db: DbOption = None,
) -> None:
    """Register a user before the robot has met them (so that their agenda can be filled),
    or update the named fields of one it knows."""
    updates: dict[str, object] = dict(_known_field(item) for item in fields or [])
    updates.update(_free_attribute(item) for item in extra or [])
    validate_fields(updates)  # a wrong field or value stores nothing, not even the user
    now = datetime.now(UTC)
    with _store(db) as store:
        store.get_or_create(user_id, now)
        profile = store.update(user_id, now, **updates) if updates else store.get(user_id)
    typer.echo(json.dumps(profile.model_dump(mode="json"), indent=2, ensure_ascii=False))


@app.command("show")
def show_user(user_id: UserArgument, db: DbOption = None) -> None:
    """Print the user's profile (no history) as JSON."""
    with _store(db) as store:
        profile = store.get(user_id)
    typer.echo(json.dumps(profile.model_dump(mode="json"), indent=2, ensure_ascii=False))


@app.command("export")
def export_user(user_id: UserArgument, db: DbOption = None) -> None:
    """Print everything stored about the user, history and agenda included, as JSON."""
    with _store(db) as store:
        data = store.export(user_id)
    typer.echo(json.dumps(data, indent=2, ensure_ascii=False))


@app.command("erase")
def erase_user(
    user_id: UserArgument,
    db: DbOption = None,
    yes: Annotated[
        bool, typer.Option("--yes", "-y", help="Erase without asking (needed off a terminal).")
    ] = False,
) -> None:
    """Delete everything stored about the user, history and agenda included.

    Asks first on a terminal; elsewhere (a script, a pipe) it needs --yes.
    """
    with _store(db) as store:
        store.get(user_id)  # an unknown user is refused before anything is asked
        if not yes:
            if not sys.stdin.isatty():
                raise ProfileError(
                    f"erase {user_id}: deletes everything stored about them; "
                    "add --yes to confirm (no terminal to ask on)"
                )
            if not typer.confirm(
                f"Erase everything stored about {user_id}, history and agenda included?"
            ):
                raise ProfileError(f"erase {user_id}: not confirmed, nothing erased")
        store.erase(user_id)
    typer.echo(f"erased {user_id}")


def upgrade_profiles(url: str) -> list[str]:
    """Bring the profile store's schema in ``url`` to the newest version; say what was done.

    ``dms db upgrade`` (the composition root, dms/cli.py) runs this, then the agenda's own.
    """
    refuse_newer(migrations.HISTORY, url, "profile")
    try:
        engine = make_engine(url)
        try:
            before = _revision(engine)
            migrations.upgrade_engine(engine)
            after = _revision(engine)
            recreated = migrations.HISTORY.recreate_missing(engine)
        finally:
            engine.dispose()
    except (SQLAlchemyError, ImportError, OSError) as error:
        raise ProfileError(f"cannot upgrade {url}: {one_line(error)}") from None
    said = [f"profiles: {before or 'empty'} -> {after}"]
    if recreated:
        said.append(f"profiles: recreated the missing table(s) {', '.join(recreated)}, empty")
    return said


def refuse_newer(history: SchemaHistory, url: str, what: str) -> None:
    """Refuse in one line a database whose ``what`` schema is at a revision this dms does
    not know: a newer dms upgraded it, and no migration here can go back from it."""
    try:
        engine = make_engine(url)
        try:
            with engine.connect() as connection:
                found = history.current(connection)
        finally:
            engine.dispose()
    except SQLAlchemyError:
        return  # the upgrade itself says what is wrong with the database
    if found is None or found == history.head():
        return
    from alembic.script import ScriptDirectory

    script = ScriptDirectory.from_config(history.config())
    if found in {revision.revision for revision in script.walk_revisions()}:
        return
    raise ProfileError(
        f"cannot upgrade {url}: its {what} schema {found} is newer than this dms knows "
        f"(up to {history.head()}); upgrade dms to use this database"
    )


def _revision(engine: Engine) -> str | None:
    with engine.connect() as connection:
        return migrations.current(connection)
