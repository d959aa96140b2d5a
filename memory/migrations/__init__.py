"""The profile store's schema migrations (Alembic), run from code.

The store shares the daemon's database with the agenda but keeps its own Alembic
history and version table (``alembic_version_memory``). ``dms db upgrade`` calls
:func:`upgrade_engine`; :class:`memory.ProfileStore` creates a brand-new database at head
and refuses one that is out of date (:class:`memory.SchemaOutOfDate`).
"""

from __future__ import annotations

from pathlib import Path

from memory.models import Base
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
)

HISTORY = SchemaHistory(HERE, VERSION_TABLE, TABLES, Base.metadata)
head = HISTORY.head
current = HISTORY.current
installed = HISTORY.installed
upgrade_engine = HISTORY.upgrade_engine
