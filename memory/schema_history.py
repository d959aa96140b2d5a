"""One package's Alembic history inside the daemon's shared database.

The profile store and the agenda share one database but each keeps its own Alembic
history and version table, so either can be upgraded, or be missing, on its own.
``memory.migrations`` and ``agenda.migrations`` each hold one :class:`SchemaHistory`.

Alembic (with Mako and Pygments: 80 ms and 12 MB) is imported only to migrate. Every
start of the daemon asks :meth:`SchemaHistory.head` and :meth:`SchemaHistory.current`;
they read the revision files' literals and the version table directly, so a restart on
a database at head never imports it, and a new database is created from the models and
stamped at head (:meth:`SchemaHistory.upgrade_engine`), so a first start does not either.
"""

from __future__ import annotations

import ast
import logging
from functools import cached_property
from importlib import import_module
from pathlib import Path
from typing import TYPE_CHECKING

from sqlalchemy import (
    Column,
    Connection,
    Engine,
    MetaData,
    PrimaryKeyConstraint,
    String,
    Table,
    column,
    insert,
    inspect,
    select,
    table,
)

if TYPE_CHECKING:
    from alembic.config import Config

log = logging.getLogger(__name__)


def _literals(path: Path) -> dict[str, object]:
    """The module-level ``name = <literal>`` assignments of one revision file."""
    out: dict[str, object] = {}
    for node in ast.parse(path.read_text(encoding="utf-8"), str(path)).body:
        target: ast.expr | None = None
        value: ast.expr | None = None
        if isinstance(node, ast.Assign) and len(node.targets) == 1:
            target, value = node.targets[0], node.value
        elif isinstance(node, ast.AnnAssign):
            target, value = node.target, node.value
        if isinstance(target, ast.Name) and value is not None:
            try:
                out[target.id] = ast.literal_eval(value)
            except ValueError:
                out[target.id] = ValueError  # not a literal: Alembic must read the file
    return out


class SchemaHistory:
    """The migrations under ``folder`` (``env.py``, ``versions/``), tracked in ``version_table``."""

    def __init__(
        self,
        folder: Path,
        version_table: str,
        tables: tuple[str, ...],
        models: str | None = None,
    ) -> None:
        """``models``: the module of the package's ORM models (its ``Base``), whose tables
        at head a new database is created from; None: always through the migrations.
        Imported only then, so that checking a database (:meth:`current`,
        :meth:`newer`) does not load the ORM."""
        self.folder = folder
        self.version_table = version_table
        self.tables = tables
        self.models = models

    def config(self, connection: Connection | None = None) -> Config:
        """Alembic's configuration, run from code (no alembic.ini)."""
        from alembic.config import Config

        config = Config()
        config.set_main_option("script_location", str(self.folder))
        config.set_main_option("path_separator", "os")
        config.set_main_option("version_locations", str(self.folder / "versions"))
        if connection is not None:
            config.attributes["connection"] = connection
        return config

    def head(self) -> str:
        """The newest revision this code knows."""
        return self._head

    @cached_property
    def _head(self) -> str:
        """Read from the revision files' ``revision`` and ``down_revision`` literals; a
        history that is not one plain chain of literals (a merge, a branch, computed
        values) is left to Alembic's ScriptDirectory, which runs the files."""
        chain = self._chain
        if chain is None:
            return self.alembic_head()
        revisions, parents = chain
        heads = revisions - parents
        if len(heads) != 1 or not parents <= revisions:
            return self.alembic_head()
        return heads.pop()

    @cached_property
    def _chain(self) -> tuple[set[str], set[str]] | None:
        """Every revision and every parent named in the revision files' literals; None
        when a file is not plain literals (Alembic must read it)."""
        revisions: set[str] = set()
        parents: set[str] = set()
        for path in sorted((self.folder / "versions").glob("*.py")):
            values = _literals(path)
            revision, down = values.get("revision"), values.get("down_revision")
            if not isinstance(revision, str) or not (down is None or isinstance(down, str)):
                return None
            if values.get("branch_labels") is not None or values.get("depends_on") is not None:
                return None
            revisions.add(revision)
            if down is not None:
                parents.add(down)
        return revisions, parents

    def newer(self, revision: str | None) -> bool:
        """Whether a database at ``revision`` was written by a newer dms: a revision this
        code does not know, from which no migration here can go back."""
        if revision is None:
            return False
        chain = self._chain
        if chain is not None:
            return revision not in chain[0]
        from alembic.script import ScriptDirectory

        script = ScriptDirectory.from_config(self.config())
        return revision not in {known.revision for known in script.walk_revisions()}

    def newer_message(self, what: str, revision: str) -> str:
        """What ``dms run`` says of a database whose ``what`` schema is at ``revision``,
        newer than this dms (:meth:`newer`), after the database's name: what to do instead."""
        return (
            f"was written by a newer version of dms ({what} schema {revision}; this dms "
            f"knows up to {self.head()}): install that version, or point --db at another "
            "database"
        )

    def alembic_head(self) -> str:
        """The head as Alembic computes it (imports Alembic and runs the revision files)."""
        from alembic.script import ScriptDirectory

        return ScriptDirectory.from_config(self.config()).get_heads()[0]

    def current(self, connection: Connection) -> str | None:
        """The revision the database is at; None when the package was never installed.

        What Alembic's ``MigrationContext.get_current_heads()[0]`` answers, read from
        the version table with one SELECT.
        """
        if not inspect(connection).has_table(self.version_table):
            return None
        versions = table(self.version_table, column("version_num"))
        return connection.execute(select(versions.c.version_num)).scalars().first()

    def installed(self, connection: Connection) -> bool:
        """Whether the package has its version table or any of its tables here."""
        names = set(inspect(connection).get_table_names())
        return self.version_table in names or any(name in names for name in self.tables)

    def upgrade_engine(self, engine: Engine, revision: str = "head") -> None:
        """Bring the package's tables on ``engine`` to ``revision`` (default: head).

        Where none of them is there yet, to head: created from the models and stamped,
        the whole in one transaction. The tables are those the migrations build (a test
        compares them); importing Alembic and running each revision took a first start
        of the daemon 0.3 s more.
        """
        if revision == "head" and self.models is not None:
            models = self.metadata()
            with engine.begin() as connection:
                if connection.dialect.name == "sqlite":
                    # pysqlite runs DDL outside any transaction unless one is open: a
                    # start stopped midway must leave no half-made schema. IMMEDIATE takes
                    # the write lock first (waiting out another writer, such as the
                    # profile writer replaying its spool), where a deferred BEGIN's read
                    # could not become a write without SQLITE_BUSY.
                    connection.exec_driver_sql("BEGIN IMMEDIATE")
                if not self.installed(connection):
                    self._create_at_head(connection, models)
                    return
        from alembic import command

        with engine.begin() as connection:
            command.upgrade(self.config(connection), revision)

    def metadata(self) -> MetaData:
        """The package's tables at head (``Base.metadata`` of :attr:`models`)."""
        assert self.models is not None, "a history without models"
        metadata: MetaData = import_module(self.models).Base.metadata
        return metadata

    def _create_at_head(self, connection: Connection, metadata: MetaData) -> None:
        head = self.head()
        log.info("new database: creating %s at %s", ", ".join(self.tables), head)
        metadata.create_all(connection, tables=[metadata.tables[name] for name in self.tables])
        # Alembic's own version table, so that later migrations find the revision.
        versions = Table(
            self.version_table,
            MetaData(),
            Column("version_num", String(32), nullable=False),
            PrimaryKeyConstraint("version_num", name=f"{self.version_table}_pkc"),
        )
        versions.create(connection)
        connection.execute(insert(versions).values(version_num=head))

    def recreate_missing(self, engine: Engine) -> list[str]:
        """Recreate, empty, the package's tables missing at head (dropped by hand, a
        partial restore): what ``dms db upgrade`` offers for a damaged database.
        Returns their names."""
        with engine.begin() as connection:
            if self.current(connection) != self.head():
                return []
            names = set(inspect(connection).get_table_names())
            missing = [name for name in self.tables if name not in names]
            if missing:
                metadata = self.metadata()
                tables = [metadata.tables[name] for name in missing]
                metadata.create_all(connection, tables=tables)
            return missing
