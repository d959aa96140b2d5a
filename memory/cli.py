"""``dms users list|show|export|erase`` and ``dms db upgrade``.

These commands open the daemon's database directly (``--db``, default the daemon's
file). They work while the daemon runs: SQLite is in WAL mode, so a reader never
blocks the daemon and an erase waits at most the busy timeout for its turn.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from typing import Annotated

import typer
from sqlalchemy import Engine
from sqlalchemy.exc import SQLAlchemyError

from memory import migrations
from memory.db import default_url, make_engine
from memory.errors import ProfileError
from memory.store import ProfileStore

app = typer.Typer(no_args_is_help=True)

db_app = typer.Typer(no_args_is_help=True)


@db_app.callback()
def _db() -> None:
    """Database schema migrations (a group, even with one command)."""


DbOption = Annotated[
    str | None, typer.Option("--db", help="SQLAlchemy database URL (default: the daemon's).")
]
UserArgument = Annotated[str, typer.Argument(help="The user id.")]


def _load_user_data_parts() -> None:
    """Import the packages that keep more about users in the same database.

    The agenda registers its items and log with the store on import, so that export
    and erase cover them; memory does not depend on it otherwise.
    """
    with suppress(ImportError):  # an install without the agenda package has none
        import agenda.service  # noqa: F401


@contextmanager
def _store(db: str | None) -> Iterator[ProfileStore]:
    _load_user_data_parts()
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


@db_app.command("upgrade")
def upgrade(db: DbOption = None) -> None:
    """Bring the database's schema (profiles and agenda) to the newest version."""
    url = db or default_url()
    try:
        engine = make_engine(url)
        try:
            before = _revision(engine)
            migrations.upgrade_engine(engine)
            after = _revision(engine)
        finally:
            engine.dispose()
    except (SQLAlchemyError, ImportError, OSError) as error:
        raise ProfileError(f"cannot upgrade {url}: {_first_line(error)}") from None
    typer.echo(f"profiles: {before or 'empty'} -> {after}")
    try:
        from agenda import migrations as agenda_migrations
    except ImportError:  # an install without the agenda package
        return
    try:
        agenda_migrations.upgrade(url)
    except (SQLAlchemyError, ImportError, OSError) as error:
        raise ProfileError(f"cannot upgrade the agenda in {url}: {_first_line(error)}") from None
    typer.echo("agenda: at head")


def _first_line(error: BaseException) -> str:
    lines = str(getattr(error, "orig", None) or error).strip().splitlines()
    return lines[0] if lines else type(error).__name__


def _revision(engine: Engine) -> str | None:
    with engine.connect() as connection:
        return migrations.current(connection)
