"""The schema check of every start reads what Alembic would, without Alembic."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from alembic.runtime.migration import MigrationContext
from sqlalchemy import create_engine

from agenda.migrations import HISTORY as AGENDA
from memory.migrations import HISTORY as MEMORY
from memory.schema_history import SchemaHistory


def test_head_is_alembics_head() -> None:
    for history in (MEMORY, AGENDA):
        assert history.head() == history.alembic_head()


def test_current_is_alembics_current_before_and_after_upgrade(tmp_path: Path) -> None:
    engine = create_engine(f"sqlite:///{tmp_path / 'dms.db'}")
    try:
        for history in (MEMORY, AGENDA):
            with engine.connect() as connection:
                assert history.current(connection) is None
            history.upgrade_engine(engine)
            with engine.connect() as connection:
                opts = {"version_table": history.version_table}
                alembic = MigrationContext.configure(connection, opts=opts).get_current_heads()
                assert history.current(connection) == alembic[0] == history.head()
    finally:
        engine.dispose()


def test_a_history_that_is_not_a_plain_chain_is_left_to_alembic(tmp_path: Path) -> None:
    versions = tmp_path / "versions"
    versions.mkdir()
    (versions / "a.py").write_text('revision = "a"\ndown_revision = None\n')
    (versions / "b.py").write_text('revision = "b"\ndown_revision = ("a", "c")\n')
    history = SchemaHistory(tmp_path, "alembic_version_test", ())
    asked: list[str] = []

    def alembic_head() -> str:
        asked.append("alembic")
        return "b"

    history.alembic_head = alembic_head  # type: ignore[method-assign]
    assert history.head() == "b"
    assert asked == ["alembic"]


def test_neither_a_first_start_nor_a_restart_imports_alembic(tmp_path: Path) -> None:
    url = f"sqlite:///{tmp_path / 'dms.db'}"
    code = (
        "import sys; from memory import ProfileStore; from agenda import Agenda;"
        f" ProfileStore({url!r}).close(); a = Agenda.open({url!r}); getattr(a, 'close', int)();"
        " print('alembic' in sys.modules)"
    )
    first = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert first.returncode == 0, first.stderr
    assert first.stdout.strip() == "False"  # a new database is created from the models
    again = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert again.returncode == 0, again.stderr
    assert again.stdout.strip() == "False"
