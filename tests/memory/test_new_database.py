"""A new database is created from the models at head, without Alembic
(tests/memory/test_schema_history_reads.py), and holds what the migrations build."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from alembic import command
from sqlalchemy import Engine, inspect

import agenda.migrations as agenda_migrations
from memory import migrations
from memory.db import make_engine
from memory.schema_history import SchemaHistory

HISTORIES = {"profiles": migrations.HISTORY, "agenda": agenda_migrations.HISTORY}


def _schema(engine: Engine, history: SchemaHistory) -> dict[str, Any]:
    """Each table's columns (by name: a migration adds columns at the end), keys,
    indexes and unique constraints, and the version table's revision."""
    seen = inspect(engine)
    schema: dict[str, Any] = {}
    for name in (*history.tables, history.version_table):
        schema[name] = {
            "columns": sorted(
                (c["name"], str(c["type"]), c["nullable"], str(c.get("default")))
                for c in seen.get_columns(name)
            ),
            "primary": seen.get_pk_constraint(name)["constrained_columns"],
            "foreign": sorted(
                (tuple(f["constrained_columns"]), f["referred_table"], str(f.get("options")))
                for f in seen.get_foreign_keys(name)
            ),
            "indexes": sorted(
                (i["name"], tuple(i["column_names"]), bool(i["unique"]))
                for i in seen.get_indexes(name)
            ),
            "unique": sorted(
                (u["name"], tuple(u["column_names"])) for u in seen.get_unique_constraints(name)
            ),
        }
    with engine.connect() as connection:
        schema["revision"] = history.current(connection)
    return schema


@pytest.mark.parametrize("package", sorted(HISTORIES))
def test_a_new_database_holds_what_the_migrations_build(tmp_path: Path, package: str) -> None:
    history = HISTORIES[package]
    migrated = make_engine(f"sqlite:///{tmp_path / 'migrated.db'}")
    with migrated.begin() as connection:
        command.upgrade(history.config(connection), "head")
    created = make_engine(f"sqlite:///{tmp_path / 'created.db'}")
    history.upgrade_engine(created)
    try:
        assert _schema(created, history) == _schema(migrated, history)
        with created.connect() as connection:
            assert history.current(connection) == history.head()
    finally:
        migrated.dispose()
        created.dispose()


def test_a_database_created_from_the_models_upgrades_as_a_migrated_one(tmp_path: Path) -> None:
    engine = make_engine(f"sqlite:///{tmp_path / 'dms.db'}")
    try:
        migrations.upgrade_engine(engine)
        with engine.begin() as connection:  # Alembic reads the stamp: nothing to run
            command.upgrade(migrations.HISTORY.config(connection), "head")
            assert migrations.current(connection) == migrations.head()
    finally:
        engine.dispose()
