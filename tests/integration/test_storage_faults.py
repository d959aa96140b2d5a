"""Storage faults of the filesystem, caused for real against a daemon process: the disk
of the database fills up (a small tmpfs) and empties again, the spool left by an
earlier run is torn, the database file is deleted while the daemon runs. The writer
never dies, nothing acknowledged is lost silently, and a damaged spool never stops a
start."""

from __future__ import annotations

import contextlib
import errno
import json
import sqlite3
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import zenoh

from tests.integration.harness import Collector, DaemonProcess, client_session, put, query

pytestmark = pytest.mark.integration

SETTLE_S = 60.0
"""How long a wait for the writes to land may take on a loaded machine (the writer's
retries back off up to 8 s)."""


@pytest.fixture
def small_disk(tmp_path: Path) -> Iterator[Path]:
    """A 32 MiB tmpfs for the database and its spool, unmounted at the end."""
    folder = tmp_path / "disk"
    folder.mkdir()
    mounted = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", "size=32m", "tmpfs", str(folder)],
        capture_output=True,
        text=True,
    )
    if mounted.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here (root and mount(8) needed): {mounted.stderr}")
    try:
        yield folder
    finally:
        subprocess.run(["umount", "-l", str(folder)], check=False)


def fill(disk: Path) -> Path:
    """Fill ``disk`` to the last byte with a filler file; returns the file."""
    filler = disk / "filler"
    with filler.open("wb", buffering=0) as out:
        for size in (1 << 20, 1 << 16, 1 << 12, 1 << 9, 1):
            try:
                while True:
                    out.write(b"\0" * size)
            except OSError as error:
                assert error.errno == errno.ENOSPC
    return filler


def arrive_and_leave(session: zenoh.Session, states: Collector, user: str) -> None:
    """``user`` comes (their profile is loaded or made, a session starts) and leaves."""
    put(session, "perception/user", {"present": True, "user_id": user, "ready": True})
    states.wait_for(lambda s: (s["user"] or {}).get("id") == user, start=states.mark() - 1)
    put(session, "perception/user", {"present": False, "user_id": None, "ready": False})
    states.wait_for(lambda s: s["user"] is None, start=states.mark() - 1)


def stored_users(db: Path) -> set[str]:
    with contextlib.closing(sqlite3.connect(db)) as connection:
        return {row[0] for row in connection.execute("SELECT user_id FROM users")}


def stored_sessions(db: Path) -> int:
    with contextlib.closing(sqlite3.connect(db)) as connection:
        (count,) = connection.execute("SELECT count(*) FROM sessions").fetchone()
    return int(count)


class Running:
    """A daemon on ``db`` with collectors on its state and errors, opened before it."""

    def __init__(self, tmp: Path, db: Path, extra_config: str = "") -> None:
        self.daemon = DaemonProcess(tmp, db=f"sqlite:///{db}", extra_config=extra_config)
        self.session = client_session(self.daemon.port)
        self.states = Collector(self.session, "robots/mini/dms/state")
        self.errors = Collector(self.session, "robots/mini/dms/errors")

    def __enter__(self) -> Running:
        try:
            self.daemon.start(self.session)
        except BaseException:
            self.session.close()  # type: ignore[no-untyped-call]
            raise
        return self

    def __exit__(self, *_: object) -> None:
        self.daemon.kill()
        self.session.close()  # type: ignore[no-untyped-call]

    def settled(self) -> None:
        """Wait for a state that says every write is in the database."""
        self.states.wait_for(
            lambda s: s["storage"] == "ok" and s["pending_writes"] == 0,
            timeout=SETTLE_S,
            start=self.states.mark(),
        )

    def degraded(self) -> None:
        self.states.wait_for(
            lambda s: s["storage"] == "degraded", timeout=SETTLE_S, start=self.states.mark() - 1
        )


USERS = [f"user{n}" for n in range(6)]


def test_a_full_disk_degrades_the_storage_and_every_write_lands_when_space_returns(
    tmp_path: Path, small_disk: Path
) -> None:
    db = small_disk / "dms.db"
    with Running(tmp_path, db) as run:
        arrive_and_leave(run.session, run.states, "ann")
        run.settled()
        filler = fill(small_disk)
        for user in USERS:
            arrive_and_leave(run.session, run.states, user)
        failed = run.errors.wait_for(lambda e: "will retry" in e["error"], timeout=SETTLE_S)
        assert "full" in failed["error"]
        given = run.errors.wait_for(lambda e: "kept for it" in e["error"], timeout=SETTLE_S)
        assert "No space left on device" in given["error"]
        assert str(small_disk / "dms.db.mini.spool.reserve") in given["error"]
        filler.unlink()
        run.settled()
        assert run.daemon.terminate() == 0
        assert sum("will retry" in e["error"] for e in run.errors.messages) == 1  # once
    assert stored_users(db) >= {"ann", *USERS}
    assert stored_sessions(db) == 1 + len(USERS)
    assert not (small_disk / "dms.db.mini.spool").exists()


def test_a_full_disk_spools_to_the_spare_folder_and_a_restart_replays_it(
    tmp_path: Path, small_disk: Path
) -> None:
    db, spare = small_disk / "dms.db", tmp_path / "spare"
    config = f'[storage]\nspool_dir = "{spare}"\n'
    spare.mkdir()
    with Running(tmp_path, db, config) as run:
        arrive_and_leave(run.session, run.states, "ann")
        run.settled()
        filler = fill(small_disk)
        for user in USERS:
            arrive_and_leave(run.session, run.states, user)
        moved = run.errors.wait_for(lambda e: "spooled to" in e["error"], timeout=SETTLE_S)
        assert str(spare / "dms.db.mini.spool") in moved["error"]
        run.degraded()
        assert run.daemon.terminate() == 0
        last = run.errors.wait_for(lambda e: "still spooled in" in e["error"])
        assert str(spare / "dms.db.mini.spool") in last["error"]
    filler.unlink()
    with Running(tmp_path, db, config) as run:
        run.settled()
        assert run.daemon.terminate() == 0
    assert stored_users(db) >= {"ann", *USERS}
    assert stored_sessions(db) == 1 + len(USERS)
    assert not (spare / "dms.db.mini.spool").exists()


def test_sigterm_on_a_full_disk_keeps_every_acknowledged_write_for_the_restart(
    tmp_path: Path, small_disk: Path
) -> None:
    """No ``spool_dir``: the space kept beside the spool takes the writes that wait."""
    db = small_disk / "dms.db"
    with Running(tmp_path, db) as run:
        arrive_and_leave(run.session, run.states, "ann")
        run.settled()
        filler = fill(small_disk)
        for user in USERS[:3]:
            arrive_and_leave(run.session, run.states, user)
        run.errors.wait_for(lambda e: "kept for it" in e["error"], timeout=SETTLE_S)
        assert run.daemon.terminate() == 0
    assert "could not be kept" not in run.daemon.log.read_text()
    filler.unlink()
    with Running(tmp_path, db) as run:
        run.settled()
        assert run.daemon.terminate() == 0
    assert stored_users(db) >= {"ann", *USERS[:3]}  # acknowledged = stored
    assert stored_sessions(db) == 1 + 3
    assert (small_disk / "dms.db.mini.spool.reserve").stat().st_size > 0  # kept again


GOOD_LINES = [
    {"op": "get_or_create", "args": [name, {"$dt": "2026-01-05T10:00:00+00:00"}], "kwargs": {}}
    for name in ("zoe", "yan")
]
TORN = {
    "bad_utf8": b'{"op": "get_or_create", "args": ["\xff"], "kwargs": {}}\n',
    "done_not_a_number": b'{"done":"1x"}\n',
    "bind_without_id": b'{"bind":"k"}\n',
}


@pytest.mark.parametrize("bad", TORN.values(), ids=list(TORN))
def test_a_torn_spool_is_set_aside_and_the_daemon_starts(tmp_path: Path, bad: bytes) -> None:
    db = tmp_path / "dms.db"
    spool = tmp_path / "dms.db.mini.spool"
    spool.write_bytes(b"".join(json.dumps(line).encode() + b"\n" for line in GOOD_LINES) + bad)
    with Running(tmp_path, db) as run:
        run.settled()
        assert run.daemon.terminate() == 0
    assert stored_users(db) >= {"zoe", "yan"}  # the good records are applied
    assert (tmp_path / "dms.db.mini.spool.bad").read_bytes() == bad
    assert not spool.exists()
    log = run.daemon.log.read_text()
    assert "1 unreadable line(s) of the spool" in log and "kept in" in log


def test_a_deleted_database_file_is_reported_and_its_writes_spooled(tmp_path: Path) -> None:
    db = tmp_path / "dms.db"
    spool = tmp_path / "dms.db.mini.spool"
    with Running(tmp_path, db) as run:
        arrive_and_leave(run.session, run.states, "ann")
        run.settled()
        db.unlink()
        arrive_and_leave(run.session, run.states, "bob")
        gone = run.errors.wait_for(lambda e: "the database file" in e["error"], timeout=SETTLE_S)
        assert str(db) in gone["error"] and "while the daemon runs" in gone["error"]
        run.degraded()
        assert run.daemon.terminate() == 0
    spooled = [json.loads(line) for line in spool.read_text().splitlines()]
    assert any(e.get("op") == "get_or_create" and e["args"][0] == "bob" for e in spooled)
    for leftover in (db, Path(f"{db}-wal"), Path(f"{db}-shm")):  # a fresh file at the path
        leftover.unlink(missing_ok=True)
    with Running(tmp_path, db) as run:
        run.settled()
        assert run.daemon.terminate() == 0
    assert "bob" in stored_users(db)  # written from the spool, not into the deleted file
    assert stored_sessions(db) == 1
    assert not spool.exists()


def test_an_agenda_add_on_a_full_disk_is_answered_once_and_closed_at_once(
    tmp_path: Path, small_disk: Path
) -> None:
    db = small_disk / "dms.db"
    with Running(tmp_path, db, "[privacy]\nserve_profiles = true\n") as run:
        arrive_and_leave(run.session, run.states, "ann")
        run.settled()
        fill(small_disk)
        add = {"op": "add", "kind": "reminder", "text": "Pills", "every": 3600}
        for _ in range(3):  # each query closes at once, not at the client's timeout
            started = time.monotonic()
            replies = query(run.session, "agenda/ann", add)
            took = time.monotonic() - started
            assert len(replies) == 1, replies
            assert took < 1.0, f"the query stayed open {took:.1f} s after its reply"
        ok, body = replies[0]
        assert not ok and "error" in body and "\n" not in body["error"]
        assert run.daemon.terminate() == 0


def test_a_link_planted_as_the_spools_bad_file_is_never_written_through(tmp_path: Path) -> None:
    db, outside = tmp_path / "dms.db", tmp_path / "outside"
    outside.write_bytes(b"precious\n")
    spool = tmp_path / "dms.db.mini.spool"
    spool.write_bytes(json.dumps(GOOD_LINES[0]).encode() + b"\n" + TORN["bad_utf8"])
    (tmp_path / "dms.db.mini.spool.bad").symlink_to(outside)
    with Running(tmp_path, db) as run:
        told = run.errors.wait_for(lambda e: "unreadable line" in e["error"], timeout=SETTLE_S)
        assert "no .bad file could be written" in told["error"]
        run.settled()
        assert run.daemon.terminate() == 0
    assert outside.read_bytes() == b"precious\n"
    assert "zoe" in stored_users(db)  # the good record is applied all the same
    log = run.daemon.log.read_text()
    assert "is a symbolic link" in log and "no .bad file could be written" in log
