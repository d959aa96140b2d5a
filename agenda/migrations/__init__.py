"""The agenda's schema migrations (Alembic), run from code.

The agenda shares the daemon's database with the profile store but keeps its own
Alembic history and version table (``alembic_version_agenda``). ``dms db upgrade``
calls :func:`upgrade`; :class:`agenda.Agenda` creates a fresh database at head and
refuses one that is out of date (:func:`is_current`).
"""

from __future__ import annotations

from pathlib import Path

from sqlalchemy import Connection, inspect

from agenda.errors import AgendaError
from memory.db import make_engine
from memory.schema_history import SchemaHistory

VERSION_TABLE = "alembic_version_agenda"
HERE = Path(__file__).resolve().parent

TABLES = ("agenda_items", "agenda_occurrences", "agenda_claims")
HISTORY = SchemaHistory(HERE, VERSION_TABLE, TABLES, "agenda.models")
head = HISTORY.head
current = HISTORY.current
installed = HISTORY.installed
upgrade_engine = HISTORY.upgrade_engine


def upgrade(url: str) -> None:
    """Bring the agenda's tables in the database at ``url`` to head."""
    engine = make_engine(url)
    try:
        upgrade_engine(engine)
        HISTORY.recreate_missing(engine)
    finally:
        engine.dispose()


def is_current(url: str) -> bool:
    """Whether the agenda's tables at ``url`` are at head."""
    engine = make_engine(url)
    try:
        with engine.connect() as connection:
            return current(connection) == head()
    finally:
        engine.dispose()


def needs_tables(connection: Connection) -> bool:
    """True when the agenda's tables are not there yet (a new database); AgendaError when
    they are there and this dms cannot use them (newer, older, one missing)."""
    revision = current(connection)
    if revision == head():
        names = set(inspect(connection).get_table_names())
        if missing := [name for name in TABLES if name not in names]:
            raise AgendaError(
                f"the database is damaged: the agenda's table {', '.join(missing)} is "
                "missing; restore a backup, or run `dms db upgrade` to recreate it empty"
            )
        return False
    if revision is None and not installed(connection):
        return True
    if HISTORY.newer(revision):
        assert revision is not None
        raise AgendaError(f"the database {HISTORY.newer_message('agenda', revision)}")
    raise AgendaError(
        f"the agenda's tables are at revision {revision or 'none'}, this dms needs "
        f"{head()}: run `dms db upgrade`"
    )
