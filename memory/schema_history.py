"""One package's Alembic history inside the daemon's shared database.

The profile store and the agenda share one database but each keeps its own Alembic
history and version table, so either can be upgraded, or be missing, on its own.
``memory.migrations`` and ``agenda.migrations`` each hold one :class:`SchemaHistory`.
"""

from __future__ import annotations

from pathlib import Path

from alembic import command
from alembic.config import Config
from alembic.runtime.migration import MigrationContext
from alembic.script import ScriptDirectory
from sqlalchemy import Connection, Engine, inspect


class SchemaHistory:
    """The migrations under ``folder`` (``env.py``, ``versions/``), tracked in ``version_table``."""

    def __init__(self, folder: Path, version_table: str, tables: tuple[str, ...]) -> None:
        self.folder = folder
        self.version_table = version_table
        self.tables = tables

    def config(self, connection: Connection | None = None) -> Config:
        """Alembic's configuration, run from code (no alembic.ini)."""
        config = Config()
        config.set_main_option("script_location", str(self.folder))
        config.set_main_option("path_separator", "os")
        config.set_main_option("version_locations", str(self.folder / "versions"))
        if connection is not None:
            config.attributes["connection"] = connection
        return config

    def head(self) -> str:
        """The newest revision this code knows."""
        return ScriptDirectory.from_config(self.config()).get_heads()[0]

    def current(self, connection: Connection) -> str | None:
        """The revision the database is at; None when the package was never installed."""
        opts = {"version_table": self.version_table}
        heads = MigrationContext.configure(connection, opts=opts).get_current_heads()
        return heads[0] if heads else None

    def installed(self, connection: Connection) -> bool:
        """Whether the package has its version table or any of its tables here."""
        names = set(inspect(connection).get_table_names())
        return self.version_table in names or any(name in names for name in self.tables)

    def upgrade_engine(self, engine: Engine, revision: str = "head") -> None:
        """Bring the package's tables on ``engine`` to ``revision`` (default: head)."""
        with engine.begin() as connection:
            command.upgrade(self.config(connection), revision)
