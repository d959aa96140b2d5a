"""The agenda's schema migrations (Alembic), run from code.

The agenda shares the daemon's database with the profile store but keeps its own
Alembic history and version table (``alembic_version_agenda``). ``dms db upgrade``
calls :func:`upgrade`; :class:`agenda.Agenda` creates a fresh database at head and
refuses one that is out of date (:func:`is_current`).
"""

from __future__ import annotations

from pathlib import Path

from agenda.models import Base
from memory.db import make_engine
from memory.schema_history import SchemaHistory

VERSION_TABLE = "alembic_version_agenda"
HERE = Path(__file__).resolve().parent

HISTORY = SchemaHistory(
    HERE, VERSION_TABLE, ("agenda_items", "agenda_occurrences", "agenda_claims"), Base.metadata
)
head = HISTORY.head
current = HISTORY.current
installed = HISTORY.installed
upgrade_engine = HISTORY.upgrade_engine


def upgrade(url: str) -> None:
    """Bring the agenda's tables in the database at ``url`` to head."""
    engine = make_engine(url)
    try:
        upgrade_engine(engine)
        HISTORY.recreate_missing(engine, Base.metadata)
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
