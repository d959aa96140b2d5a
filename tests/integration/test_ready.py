"""What "ready" means for ``dms run``: ``alive/dms`` is declared once the daemon has
published its first state and hears its inputs, on a database it has checked it can use;
the profile store and the agenda open right after it, before the next tick, and a
``users/`` or ``agenda/`` query asked meanwhile waits for them rather than failing.

Each case is a real daemon process on a free loopback port and a real SQLite file;
every wait is for a token, a reply or a line on stderr.
"""

from __future__ import annotations

import signal
import subprocess
import sys
from datetime import UTC, datetime
from pathlib import Path

import pytest

from memory import ProfileStore
from tests.integration.harness import (
    READY_TIMEOUT_S,
    DaemonProcess,
    StderrLines,
    client_session,
    free_port,
    query,
)

pytestmark = pytest.mark.integration

STORE_AND_AGENDA = {"sqlalchemy.orm", "agenda.models", "memory.models", "dms.profiles"}
"""Modules of the database layer, which load after ready (``-X importtime`` has no line
for a module loaded by ``importlib.import_module``, as ``agenda.service`` is)."""


def _imports(lines: list[str]) -> set[str]:
    """The modules of ``python -X importtime`` lines."""
    return {line.rsplit("|", 1)[1].strip() for line in lines if line.startswith("import time:")}


def _run(db: Path, *python_flags: str) -> list[str]:
    """``dms run`` on ``db`` and a free loopback port."""
    command = [sys.executable, *python_flags, "-m", "dms.cli", "run", "--quiet"]
    return [*command, "--db", str(db), "--listen", f"tcp/127.0.0.1:{free_port()}", "--seed", "1"]


def test_the_store_and_the_agenda_load_after_ready(tmp_path: Path) -> None:
    command = [*_run(tmp_path / "dms.db", "-X", "importtime"), "--log-level", "info"]
    proc = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        lines = StderrLines(proc)
        lines.wait_for("ready on", READY_TIMEOUT_S)
        ready = lines.mark()
        # the store's service is imported after the ready line
        lines.wait_for(lambda line: _imports([line]) == {"dms.profiles"}, READY_TIMEOUT_S, ready)
        proc.send_signal(signal.SIGINT)
        assert proc.wait(30) == 130, lines.text()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(10)
    before, after = lines.lines[:ready], lines.lines[ready:]
    assert {"dms.daemon", "dms.controller.tick"} <= _imports(before)  # the log is read right
    assert not STORE_AND_AGENDA & _imports(before)
    assert _imports(after) >= STORE_AND_AGENDA


def test_a_query_asked_at_ready_waits_for_the_store_and_is_answered(tmp_path: Path) -> None:
    """A client that queries as soon as it sees ``alive/dms`` gets its answer, from the
    database the daemon found (a restart: users stored before it)."""
    db = tmp_path / "dms.db"
    store = ProfileStore(f"sqlite:///{db}")
    store.get_or_create("ann", datetime(2026, 11, 28, 9, tzinfo=UTC))
    store.close()
    daemon = DaemonProcess(
        tmp_path, db=f"sqlite:///{db}", extra_config="[privacy]\nserve_profiles = true\n"
    )
    session = client_session(daemon.port)
    try:
        daemon.start(session)  # returns as soon as alive/dms is seen
        assert query(session, "users/*") == [(True, {"users": ["ann"]})]
        [(ok, body)] = query(session, "agenda/ann")
        assert ok, body
        assert daemon.terminate() == 0
    finally:
        daemon.kill()
        session.close()


def test_a_database_it_cannot_use_is_refused_before_ready(tmp_path: Path) -> None:
    """The store and the agenda load after ready, but the database is checked before: a
    file that is no database ends ``dms run`` with exit 1 and one line naming it, and
    the daemon never said it was ready."""
    bad = tmp_path / "dms.db"
    bad.write_bytes(b"this is not an SQLite database, " * 64)
    done = subprocess.run(
        [*_run(bad), "--log-level", "info"], capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 1, done.stderr
    assert done.stderr.strip().splitlines() == [
        f"dms: database {bad}: cannot open database sqlite:///{bad}: file is not a database"
    ]
    assert bad.read_bytes().startswith(b"this is not an SQLite database")  # left as it was
