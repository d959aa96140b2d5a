"""``dms users list|add|show|export|erase`` and ``dms db upgrade``.

These commands open the daemon's database directly (``--db``, default the daemon's
file). They work while the daemon runs: SQLite is in WAL mode, so a reader never
blocks the daemon and an erase waits at most the busy timeout for its turn.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from contextlib import contextmanager
from datetime import UTC, datetime
from typing import Annotated

import typer
from sqlalchemy import Engine
from sqlalchemy.exc import SQLAlchemyError

from memory import migrations
from memory.db import default_url, make_engine
from memory.errors import ProfileError
from memory.profile import validate_fields
from memory.store import ProfileStore

app = typer.Typer(no_args_is_help=True)

DbOption = Annotated[
    str | None, typer.Option("--db", help="SQLAlchemy database URL (default: the daemon's).")
]
UserArgument = Annotated[str, typer.Argument(help="The user id.")]


@contextmanager
def _store(db: str | None) -> Iterator[ProfileStore]:
    store = ProfileStore(db or default_url())
    try:
        yield store
    finally:
        store.close()


@app.command("list")
def list_users(db: DbOption = None) -> None:
    """Print every stored user id, one a line."""
    with _store(db) as store:
        for user_id in store.list_ids():
            typer.echo(user_id)


def _literal(raw: str) -> object:
    """A JSON literal when ``raw`` parses as one (``72``, ``true``), else the text itself."""
    try:
        return json.loads(raw)
    except ValueError:
        return raw


@app.command("add")
def add_user(
    user_id: UserArgument,
    fields: Annotated[
        list[str] | None,
        typer.Option("--set", help="A profile field, NAME=VALUE (e.g. name=Ann, age=81)."),
    ] = None,
    db: DbOption = None,
) -> None:
    """Register a user before the robot has met them (so that their agenda can be filled),
    or update the named fields of one it knows."""
    updates: dict[str, object] = {}
    for item in fields or []:
        name, sep, raw = item.partition("=")
        if not sep or not name.strip():
            raise ProfileError(f"--set {item!r}: expected NAME=VALUE")
        updates[name.strip()] = _literal(raw)
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
def erase_user(user_id: UserArgument, db: DbOption = None) -> None:
    """Delete everything stored about the user, history and agenda included."""
    with _store(db) as store:
        store.erase(user_id)
    typer.echo(f"erased {user_id}")


def upgrade_profiles(url: str) -> list[str]:
    """Bring the profile store's schema in ``url`` to the newest version; say what was done.

    ``dms db upgrade`` (the composition root, dms/cli.py) runs this, then the agenda's own.
    """
    try:
        engine = make_engine(url)
        try:
            before = _revision(engine)
            migrations.upgrade_engine(engine)
            after = _revision(engine)
            from memory.models import Base

            recreated = migrations.HISTORY.recreate_missing(engine, Base.metadata)
        finally:
            engine.dispose()
    except (SQLAlchemyError, ImportError, OSError) as error:
        raise ProfileError(f"cannot upgrade {url}: {first_line(error)}") from None
    said = [f"profiles: {before or 'empty'} -> {after}"]
    if recreated:
        said.append(f"profiles: recreated the missing table(s) {', '.join(recreated)}, empty")
    return said


def first_line(error: BaseException) -> str:
    lines = str(getattr(error, "orig", None) or error).strip().splitlines()
    return lines[0] if lines else type(error).__name__


def _revision(engine: Engine) -> str | None:
    with engine.connect() as connection:
        return migrations.current(connection)
