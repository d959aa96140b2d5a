"""New user ids as a peer on the network sends them to one real ``dms run`` over real
Zenoh on 127.0.0.1, and ``dms db upgrade``/``dms run`` on a database a newer dms made.

- a flood of distinct ready ids, each seen for a moment: no user row is made;
- a user ready and engaged past ``new_user_after_s`` gets her profile;
- ids held ready past it beyond ``new_profiles_per_hour``: the rows stay within the
  cap, and the ids refused are reported once, with their count;
- a database stamped with a revision this dms does not know: one line, no traceback,
  a non-zero exit.

Every wait is for a message or a row, with a deadline; every flood is bounded.
"""

from __future__ import annotations

import sqlite3
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import closing
from pathlib import Path

import pytest
import zenoh

from tests.integration.harness import Collector, DaemonProcess, client_session, paced, put
from tests.integration.hostile import Reports, assert_alive, sentinel

pytestmark = pytest.mark.integration

AFTER_S = 1.0
PER_HOUR = 3
FLOOD = 200
FLOOD_RATE = 50.0
HELD_S = 3.0
"""How long each held id is shown ready: the daemon's first tick may see it 0.5 s late,
and the tick due at AFTER_S after that a few milliseconds early (then the next one)."""

REFUSED = "new user ids not stored"


def _users(db: Path) -> list[str]:
    with closing(sqlite3.connect(db)) as connection:
        return [row[0] for row in connection.execute("SELECT user_id FROM users ORDER BY 1")]


def _wait_users(db: Path, expected: list[str], timeout: float = 20.0) -> None:
    """Until the users table holds ``expected`` (the writer thread writes off the tick)."""
    deadline = time.monotonic() + timeout
    while (found := _users(db)) != expected:
        assert time.monotonic() < deadline, f"users {found}, not {expected}"
        time.sleep(0.1)  # ok-sleep: polls a file another process writes, to a deadline


def _ready(user_id: str) -> dict[str, object]:
    return {"present": True, "user_id": user_id, "ready": True, "engagement": 0.8}


def _hold(session: zenoh.Session, user_id: str) -> None:
    """Show ``user_id`` ready and engaged for HELD_S (10 messages a second)."""
    for _ in paced(range(int(HELD_S * 10)), 10.0):
        put(session, "perception/user", _ready(user_id))


def test_a_user_id_flood_stays_within_the_hourly_cap_and_is_reported_once(
    tmp_path: Path,
) -> None:
    db = tmp_path / "dms.db"
    config = f"new_profiles_per_hour = {PER_HOUR}\n"
    daemon = DaemonProcess(tmp_path, extra_config=config, new_user_after_s=AFTER_S)
    session = client_session(daemon.port)
    try:
        daemon.start(session)
        states = Collector(session, "robots/mini/dms/state")
        reports = Reports(session)
        states.wait_count(1)
        # a flood of ids, each ready for a fiftieth of a second: none qualifies
        for index in paced(range(FLOOD), FLOOD_RATE):
            put(session, "perception/user", _ready(f"ghost{index}"))
        put(session, "perception/user", {"present": False, "user_id": None, "ready": False})
        sentinel(session, reports, "perception/user")  # every flood message was read
        states.wait_count(states.mark() + 3)  # and ticked over
        assert _users(db) == []
        # a genuine user, ready and engaged past the wait
        _hold(session, "ann")
        _wait_users(db, ["ann"])
        # more new ids held ready than the hour allows: two more are stored, three refused
        first = reports.mark()
        held = [f"visitor{index}" for index in range(5)]
        for user_id in held:
            _hold(session, user_id)
        put(session, "perception/user", {"present": False, "user_id": None, "ready": False})
        _, report = reports.wait_for(lambda r: REFUSED in r["error"], start=first, timeout=30)
        assert report["key"] == "perception/user"
        assert report["error"].startswith(f"3 {REFUSED} in the last "), report
        assert _users(db) == ["ann", "visitor0", "visitor1"]
        # reported once: nothing more is said of them
        end = sentinel(session, reports, "perception/user", first)
        states.wait_count(states.mark() + 3)
        said = [r for r in reports.all()[first:] if REFUSED in r["error"]]
        assert len(said) == 1, said
        assert end > reports.all().index(report)
        assert_alive(daemon, session, states)
        assert daemon.terminate() == 0
    finally:
        daemon.kill()
        session.close()
    log = daemon.log.read_text()
    assert log.count(REFUSED) == 1, log[-3000:]


# ---------------------------------------------------------------- a newer schema


@pytest.fixture
def newer_db(tmp_path: Path) -> Iterator[Path]:
    """A database at head, its profile schema then stamped with a revision from the
    future (what a newer dms's ``dms db upgrade`` leaves)."""
    db = tmp_path / "newer.db"
    made = _dms("db", "upgrade", "--db", str(db))
    assert made.returncode == 0, made.stderr
    with closing(sqlite3.connect(db)) as connection:
        connection.execute("UPDATE alembic_version_memory SET version_num = 'memory_9999'")
        connection.commit()
    yield db


def _dms(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "dms.cli", *args],
        capture_output=True,
        text=True,
        timeout=60,
    )


def test_db_upgrade_on_a_newer_schema_says_so_in_one_line_and_fails(newer_db: Path) -> None:
    done = _dms("db", "upgrade", "--db", str(newer_db))
    assert done.returncode != 0
    assert "Traceback" not in done.stderr + done.stdout
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr
    assert "memory_9999 is newer than this dms" in lines[0]
    assert "upgrade dms" in lines[0]
    with closing(sqlite3.connect(newer_db)) as connection:  # nothing was changed
        stamp = connection.execute("SELECT version_num FROM alembic_version_memory").fetchall()
    assert stamp == [("memory_9999",)]


def test_run_on_a_newer_schema_is_refused_in_one_line(newer_db: Path, tmp_path: Path) -> None:
    done = _dms("run", "--db", str(newer_db), "--listen", "tcp/127.0.0.1:0")
    assert done.returncode != 0
    assert "Traceback" not in done.stderr + done.stdout
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr
    assert "memory_9999" in lines[0]
