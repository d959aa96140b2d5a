"""The profile store's schema migrations (Alembic), run from code.

The store shares the daemon's database with the agenda but keeps its own Alembic
history and version table (``alembic_version_memory``). ``dms db upgrade`` calls
:func:`upgrade`; :class:`memory.ProfileStore` creates a brand-new database at head
and refuses one that is out of date (:class:`memory.SchemaOutOfDate`).
"""

from __future__ import annotations

from pathlib import Path

from alembic import command
from alembic.config import Config
from alembic.runtime.migration import MigrationContext
from alembic.script import ScriptDirectory
from sqlalchemy import Connection, Engine, inspect

VERSION_TABLE = "alembic_version_memory"
HERE = Path(__file__).resolve().parent
TABLES = ("users", "activity_scores", "sessions", "activity_runs", "feedback", "answers")


def _config(connection: Connection | None = None) -> Config:
    config = Config()
    config.set_main_option("script_location", str(HERE))
    config.set_main_option("path_separator", "os")
    config.set_main_option("version_locations", str(HERE / "versions"))
    if connection is not None:
        config.attributes["connection"] = connection
    return config


def head() -> str:
    """The newest revision this code knows."""
    heads = ScriptDirectory.from_config(_config()).get_heads()
    return heads[0]


def current(connection: Connection) -> str | None:
    """The revision the database is at; None when the store was never installed."""
    context = MigrationContext.configure(connection, opts={"version_table": VERSION_TABLE})
    heads = context.get_current_heads()
    return heads[0] if heads else None


def installed(connection: Connection) -> bool:
    """Whether the store has a version table or any of its tables in this database."""
    names = set(inspect(connection).get_table_names())
    return VERSION_TABLE in names or any(name in names for name in TABLES)


def upgrade_engine(engine: Engine, revision: str = "head") -> None:
    """Bring the store's tables on ``engine`` to ``revision`` (default: head)."""
    with engine.begin() as connection:
        command.upgrade(_config(connection), revision)
