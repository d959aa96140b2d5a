"""The agenda's schema migrations (Alembic), run from code.

The agenda shares the daemon's database with the profile store but keeps its own
Alembic history and version table (``alembic_version_agenda``). ``dms db upgrade``
calls :func:`upgrade`; :class:`agenda.Agenda` creates a fresh database at head and
refuses one that is out of date (:func:`is_current`).
"""

from __future__ import annotations

from pathlib import Path

from alembic import command
from alembic.config import Config
from alembic.runtime.migration import MigrationContext
from alembic.script import ScriptDirectory
from sqlalchemy import Connection, Engine, inspect

from memory.db import make_engine

VERSION_TABLE = "alembic_version_agenda"
HERE = Path(__file__).resolve().parent


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
    """The revision the database is at; None when the agenda was never installed."""
    context = MigrationContext.configure(connection, opts={"version_table": VERSION_TABLE})
    heads = context.get_current_heads()
    return heads[0] if heads else None


def upgrade_engine(engine: Engine) -> None:
    """Bring the agenda's tables on ``engine`` to head."""
    with engine.begin() as connection:
        command.upgrade(_config(connection), "head")


def upgrade(url: str) -> None:
    """Bring the agenda's tables in the database at ``url`` to head."""
    engine = make_engine(url)
    try:
        upgrade_engine(engine)
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


def installed(connection: Connection) -> bool:
    """Whether the agenda has a version table or tables in this database."""
    names = set(inspect(connection).get_table_names())
    return VERSION_TABLE in names or "agenda_items" in names
