"""``dms run`` on a database a newer dms wrote: the real command in a subprocess, on a
SQLite file whose profile or agenda schema is stamped with a revision this dms does not
know. It refuses in one line that says a newer dms wrote the database and what to do
instead; it never advises ``dms db upgrade``, which cannot go back from a newer schema.
"""

from __future__ import annotations

import sqlite3
import subprocess
import sys
from contextlib import closing
from pathlib import Path

import pytest

pytestmark = pytest.mark.integration


def _dms(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "dms.cli", *args],
        capture_output=True,
        text=True,
        timeout=60,
    )


def _database_stamped(tmp_path: Path, table: str, revision: str) -> Path:
    """A database at head made by ``dms db upgrade``, then ``table`` stamped ``revision``."""
    db = tmp_path / "dms.db"
    made = _dms("db", "upgrade", "--db", str(db))
    assert made.returncode == 0, made.stderr
    with closing(sqlite3.connect(db)) as connection:
        connection.execute(f"UPDATE {table} SET version_num = ?", (revision,))
        connection.commit()
    return db


@pytest.mark.parametrize(
    ("table", "revision", "what"),
    [
        ("alembic_version_memory", "memory_9999", "profile schema memory_9999"),
        ("alembic_version_agenda", "agenda_9999", "agenda schema agenda_9999"),
    ],
)
def test_run_on_a_newer_schema_says_a_newer_dms_wrote_it_in_one_line(
    tmp_path: Path, table: str, revision: str, what: str
) -> None:
    db = _database_stamped(tmp_path, table, revision)
    done = _dms("run", "--db", str(db), "--listen", "tcp/127.0.0.1:0")
    assert done.returncode != 0
    assert "Traceback" not in done.stderr + done.stdout
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr
    line = lines[0]
    assert line.startswith("dms: "), line
    assert "written by a newer version of dms" in line
    assert what in line
    assert "install that version, or point --db at another database" in line
    assert "db upgrade" not in line
    with closing(sqlite3.connect(db)) as connection:  # nothing was changed
        stamp = connection.execute(f"SELECT version_num FROM {table}").fetchall()
    assert stamp == [(revision,)]


def test_run_on_an_older_schema_still_advises_db_upgrade(tmp_path: Path) -> None:
    db = _database_stamped(tmp_path, "alembic_version_memory", "memory_0001")
    done = _dms("run", "--db", str(db), "--listen", "tcp/127.0.0.1:0")
    assert done.returncode != 0
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr
    assert "dms db upgrade" in lines[0]
    assert "newer version" not in lines[0]
