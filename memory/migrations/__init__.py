"""The profile store's schema migrations (Alembic), run from code.

The store shares the daemon's database with the agenda but keeps its own Alembic
history and version table (``alembic_version_memory``). ``dms db upgrade`` calls
:func:`upgrade_engine`; :class:`memory.ProfileStore` creates a brand-new database at head
and refuses one that is out of date (:class:`memory.SchemaOutOfDate`), as
:func:`open_checked` finds it. Without the ORM: the daemon checks its database before
it is ready and loads the store after.
"""

from __future__ import annotations

from pathlib import Path

from sqlalchemy import Connection, Engine, inspect
from sqlalchemy.exc import ArgumentError, SQLAlchemyError

from memory.db import make_engine, shown_url
from memory.errors import ProfileError, SchemaOutOfDate, StoreDamaged, one_line
from memory.schema_history import SchemaHistory

VERSION_TABLE = "alembic_version_memory"
HERE = Path(__file__).resolve().parent
TABLES = (
    "users",
    "activity_scores",
    "sessions",
    "activity_runs",
    "feedback",
    "answers",
    "applied_writes",
    "interaction_events",
)

HISTORY = SchemaHistory(HERE, VERSION_TABLE, TABLES, "memory.models")
head = HISTORY.head
current = HISTORY.current
installed = HISTORY.installed
upgrade_engine = HISTORY.upgrade_engine


def open_checked(url: str, busy_timeout_s: float | None = None) -> tuple[Engine, bool]:
    """An engine on the database at ``url`` (a URL, see :func:`memory.db.as_url`) whose
    profile schema this dms can use, and whether the store's tables are still to be made
    (a new database).

    Raises:
        ProfileError: it cannot be opened, or a newer dms wrote it.
        SchemaOutOfDate: it needs ``dms db upgrade --db URL``.
        StoreDamaged: one of the store's tables is missing.
    """
    try:
        shown = shown_url(url)
    except ArgumentError as error:
        raise ProfileError(f"cannot open database {url!r}: {error}") from None
    engine: Engine | None = None
    try:
        engine = make_engine(url, busy_timeout_s)
        with engine.connect() as connection:
            return engine, _new_or_refused(connection, shown)
    except (SQLAlchemyError, OSError, ImportError) as error:
        if engine is not None:
            engine.dispose()
        raise ProfileError(f"cannot open database {shown}: {one_line(error)}") from None
    except ProfileError:
        assert engine is not None
        engine.dispose()
        raise


def _new_or_refused(connection: Connection, shown: str) -> bool:
    """True when the store's tables are not there yet; raises when they cannot be used."""
    if not installed(connection):
        return True
    revision = current(connection)
    if HISTORY.newer(revision):
        assert revision is not None
        raise ProfileError(f"database {shown} {HISTORY.newer_message('profile', revision)}")
    if revision != head():
        raise SchemaOutOfDate(
            f"database {shown} has profile schema {revision or 'unversioned'}, "
            f"this dms needs {head()}: run `dms db upgrade --db {shown}`"
        )
    tables = set(inspect(connection).get_table_names())
    if missing := [name for name in TABLES if name not in tables]:
        raise StoreDamaged(
            f"database {shown} is damaged: table {', '.join(missing)} missing at schema "
            f"{head()}; restore a backup, or run `dms db upgrade --db {shown}` to recreate "
            "it empty"
        )
    return False
