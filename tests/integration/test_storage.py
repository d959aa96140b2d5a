"""Storage faults caused for real against a daemon process: another process holding
SQLite's write lock (the loop keeps its 2 Hz, the writes are spooled), kill -9 while the
database is locked (nothing acknowledged is lost after a restart), a table dropped
mid-run (that write is quarantined and reported, the others land; a restart is refused
with the repair, and ``dms db upgrade`` repairs it)."""

from __future__ import annotations

import itertools
import json
import sqlite3
import subprocess
import sys
from datetime import datetime
from pathlib import Path
from typing import Any

import pytest
import zenoh

from tests.integration.harness import Collector, DaemonProcess, client_session, put, running_daemon

pytestmark = pytest.mark.integration

ANN_READY = {"present": True, "user_id": "ann", "ready": True}
ROOT = Path(__file__).resolve().parents[2]
HOLD = """
import sqlite3, sys
connection = sqlite3.connect(sys.argv[1], isolation_level=None, timeout=30)
connection.execute("BEGIN EXCLUSIVE")
print("locked", flush=True)
sys.stdin.readline()
connection.execute("ROLLBACK")
print("released", flush=True)
"""


class LockHolder:
    """Another process that holds SQLite's write lock until told to let go."""

    def __init__(self, db: Path) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, "-c", HOLD, str(db)],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
        )
        assert self.proc.stdout is not None
        assert self.proc.stdout.readline().strip() == "locked"

    def release(self) -> None:
        assert self.proc.stdin is not None and self.proc.stdout is not None
        self.proc.stdin.write("go\n")
        self.proc.stdin.flush()
        assert self.proc.stdout.readline().strip() == "released"
        self.proc.wait(10)


def _ts(state: dict[str, Any]) -> float:
    return datetime.fromisoformat(state["time"]).timestamp()


def jokes_round(session: zenoh.Session, decisions: Collector) -> None:
    """Start jokes for ann, then cancel it: one ``record_activity`` write."""
    mark = decisions.mark()
    put(session, "request", {"action": "start", "activity": "jokes", "by": "ann"})
    decisions.wait_for(
        lambda d: d["action"] == "start" and d["activity"] == "jokes", start=mark, timeout=15
    )
    mark = decisions.mark()
    put(session, "request", {"action": "cancel", "activity": "jokes", "by": "ann"})
    decisions.wait_for(
        lambda d: d["action"] == "cancel" and d["activity"] == "jokes", start=mark, timeout=15
    )


def pace(states: Collector) -> None:
    """Wait for a periodic tick (half a second on): a user's pace, under the rate caps."""
    after = _ts(states.messages[-1]) + 0.45
    states.wait_for(lambda s: _ts(s) >= after, start=states.mark())


def jokes_runs(db: Path) -> int:
    with sqlite3.connect(db) as connection:
        (count,) = connection.execute(
            "SELECT count(*) FROM activity_runs WHERE user_id = 'ann' AND activity = 'jokes'"
            " AND cancelled"
        ).fetchone()
    return int(count)


def begin_session(session: zenoh.Session) -> Collector:
    states = Collector(session, "robots/mini/dms/state")
    put(session, "perception/user", ANN_READY)
    states.wait_for(lambda s: (s["user"] or {}).get("id") == "ann" or s["user"] is not None)
    return states


def test_a_lock_held_20_s_by_another_process_costs_the_loop_no_tick(tmp_path: Path) -> None:
    db = tmp_path / "dms.db"
    with running_daemon(tmp_path) as (daemon, session):
        decisions = Collector(session, "robots/mini/dms/decision")
        errors = Collector(session, "robots/mini/dms/errors")
        states = begin_session(session)
        jokes_round(session, decisions)
        holder = LockHolder(db)
        start = states.mark()
        first = states.wait_for(lambda s: True, start=start)
        rounds = 0
        while _ts(states.messages[-1]) - _ts(first) < 20:
            jokes_round(session, decisions)
            rounds += 1
            pace(states)
        end = states.mark()
        holder.release()
        times = [_ts(s) for s in states.messages[start:end]]
        gaps = [b - a for a, b in itertools.pairwise(times)]
        assert max(gaps) <= 0.6, f"longest dms/state gap {max(gaps):.3f} s"
        spooled = errors.wait_for(lambda e: "spooled" in e["error"])
        assert "database is locked" in spooled["error"]
        assert daemon.terminate() == 0
    assert jokes_runs(db) == rounds + 1  # every write made under the lock landed after it
    assert not Path(f"{db}.mini.spool").exists()


def test_kill_9_while_locked_then_restart_loses_nothing_acknowledged(tmp_path: Path) -> None:
    db = tmp_path / "dms.db"
    with running_daemon(tmp_path) as (daemon, session):
        decisions = Collector(session, "robots/mini/dms/decision")
        errors = Collector(session, "robots/mini/dms/errors")
        states = begin_session(session)
        holder = LockHolder(db)
        jokes_round(session, decisions)
        errors.wait_for(lambda e: "spooled" in e["error"], timeout=15)
        for _ in range(5):  # acknowledged: in the spool before their decision is published
            jokes_round(session, decisions)
            pace(states)
        daemon.kill()
    spooled = Path(f"{db}.mini.spool").read_text().splitlines()
    assert sum('"record_activity"' in line for line in spooled) >= 6
    holder.release()
    again = DaemonProcess(tmp_path)
    session = client_session(again.port)
    try:
        again.start(session)
        assert again.terminate() == 0
    finally:
        again.kill()
        session.close()
    assert jokes_runs(db) >= 6
    assert not Path(f"{db}.mini.spool").exists()


def test_a_dropped_table_quarantines_its_write_and_a_restart_is_refused(tmp_path: Path) -> None:
    db = tmp_path / "dms.db"
    url = f"sqlite:///{db}"
    with running_daemon(tmp_path) as (daemon, session):
        decisions = Collector(session, "robots/mini/dms/decision")
        errors = Collector(session, "robots/mini/dms/errors")
        states = begin_session(session)
        with sqlite3.connect(db) as connection:
            connection.execute("DROP TABLE activity_runs")
        jokes_round(session, decisions)
        refused = errors.wait_for(lambda e: "record_activity refused" in e["error"])
        assert "no such table: activity_runs" in refused["error"]
        assert f"{db}.mini.quarantine" in refused["error"]
        put(session, "perception/user", {"present": False})  # ends the session: another table
        states.wait_for(lambda s: s["user"] is None)
        assert daemon.terminate() == 0
    # jokes, and whatever the robot chose next and cancelled when ann left
    entries = [json.loads(line) for line in Path(f"{db}.mini.quarantine").read_text().splitlines()]
    assert {entry["op"] for entry in entries} == {"record_activity"}
    assert entries[0]["args"][:2] == ["ann", "jokes"] and "activity_runs" in entries[0]["error"]
    with sqlite3.connect(db) as connection:
        (ended,) = connection.execute("SELECT ended_at FROM sessions").fetchone()
    assert ended is not None
    run = [sys.executable, "-m", "dms.cli"]
    refused_start = subprocess.run(
        [*run, "run", "--db", url, "--listen", "tcp/127.0.0.1:0"],
        capture_output=True,
        text=True,
        timeout=60,
        cwd=ROOT,
    )
    assert refused_start.returncode != 0
    lines = refused_start.stderr.strip().splitlines()
    assert len(lines) == 1, refused_start.stderr
    assert "activity_runs" in lines[0] and f"dms db upgrade --db {url}" in lines[0]
    upgrade = subprocess.run(
        [*run, "db", "upgrade", "--db", url], capture_output=True, text=True, timeout=60, cwd=ROOT
    )
    assert upgrade.returncode == 0 and "activity_runs" in upgrade.stdout
    with sqlite3.connect(db) as connection:
        assert connection.execute("SELECT count(*) FROM activity_runs").fetchone() == (0,)
