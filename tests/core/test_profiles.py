"""The controller's ProfileService through real database faults: a lock held by another
connection (passing: the writes are spooled, in order, and replayed), a dropped table or
a value the database refuses (for good: that write is quarantined, the rest go on), a
restart with writes still spooled. Real SQLite files, and the real PostgreSQL when
``DMS_TEST_POSTGRES_URL`` is set."""

from __future__ import annotations

import json
import sqlite3
import time
from collections.abc import Iterator
from datetime import UTC, datetime, timedelta
from pathlib import Path

import pytest
from sqlalchemy import text

from dms.profiles import RETRY_EVERY_S, ProfileService
from memory import ProfileStore
from tests.postgres import POSTGRES_URL, fresh_schema

NOW = datetime(2026, 11, 23, 10, 0, tzinfo=UTC)
LATER = NOW + timedelta(seconds=RETRY_EVERY_S)
Reports = list[tuple[str, str]]


class Lock:
    """Another connection holding SQLite's write lock, as a backup or the CLI would."""

    def __init__(self, path: Path) -> None:
        self.connection = sqlite3.connect(path, isolation_level=None)

    def __enter__(self) -> Lock:
        self.connection.execute("BEGIN EXCLUSIVE")
        return self

    def __exit__(self, *_exc: object) -> None:
        self.connection.execute("ROLLBACK")
        self.connection.close()


@pytest.fixture
def db(tmp_path: Path) -> Path:
    return tmp_path / "dms.db"


@pytest.fixture
def store(db: Path) -> Iterator[ProfileStore]:
    profiles = ProfileStore(f"sqlite:///{db}", busy_timeout_s=0.05)
    yield profiles
    profiles.close()


@pytest.fixture
def reports() -> Reports:
    return []


def service_of(store: ProfileStore, reports: Reports, **options: object) -> ProfileService:
    return ProfileService(store, lambda key, line: reports.append((key, line)), **options)  # type: ignore[arg-type]


def test_a_lock_spools_the_writes_in_order_with_one_line_and_replays_them(
    store: ProfileStore, db: Path, reports: Reports
) -> None:
    service = service_of(store, reports, threaded=False)
    loaded = service.load("ann", NOW)
    assert loaded is not None and loaded.user_id == "ann"
    with Lock(db):
        assert service.load("ann", NOW) == loaded  # a read: WAL lets it through the lock
        service.record_feedback("ann", "quiz", 0.25, NOW)
        service.update("ann", NOW, name="Old")
        service.record_feedback("ann", "quiz", 0.75, NOW + timedelta(seconds=1))
        service.update("ann", NOW, name="New")
        assert service.pending_writes == 4
        service.retry(LATER)  # still locked: everything stays, nothing more is reported
    ((key, line),) = reports
    assert key == "memory" and "\n" not in line
    assert "database is locked" in line and f"{db}.spool" in line
    assert len(Path(f"{db}.spool").read_text().splitlines()) == 4  # on disk, fsync'd
    service.retry(LATER + timedelta(seconds=1))  # too soon after the last try
    assert service.pending_writes == 4
    service.retry(LATER + timedelta(seconds=RETRY_EVERY_S + 1))
    assert service.pending_writes == 0
    exported = store.export("ann")
    assert [f["score"] for f in exported["feedback"]] == [0.25, 0.75]
    assert exported["profile"]["name"] == "New"  # the later update wins
    assert service.cached("ann") == store.get("ann")
    service.close()
    assert not Path(f"{db}.spool").exists()


def test_the_writer_thread_never_makes_the_caller_wait_and_nothing_is_lost(
    store: ProfileStore, db: Path, reports: Reports
) -> None:
    service = service_of(store, reports, queue_size=4)
    assert service.load("ann", NOW, wait_s=5.0) is not None
    with Lock(db):
        started = time.monotonic()
        for n in range(40):
            service.record_feedback("ann", "quiz", n / 40, NOW + timedelta(seconds=n))
        assert time.monotonic() - started < 0.5  # 40 writes against a locked database
        assert service.pending_writes == 40
    assert service.writer.wait_idle(10.0)
    scores = [f["score"] for f in store.export("ann")["feedback"]]
    assert scores == [n / 40 for n in range(40)]
    assert service.close() == 0


def test_a_clean_exit_keeps_the_spool_and_the_next_start_replays_it(
    store: ProfileStore, db: Path, reports: Reports
) -> None:
    service = service_of(store, reports)
    assert service.load("ann", NOW, wait_s=5.0) is not None
    with Lock(db):
        session = service.start_session("ann", NOW)
        assert isinstance(session, str)
        service.record_activity("ann", "quiz", NOW, LATER, "completed", "robot", False, session)
        service.end_session(session, LATER)
        service.update("ann", LATER, name="Ann")
        assert service.close() == 4
    assert reports[-1][1].endswith(
        f"4 write(s) still spooled in {db}.spool; they are replayed at the next start"
    )
    assert store.get("ann").name is None  # not written yet, but not lost
    again = service_of(store, reports)
    assert again.writer.wait_idle(10.0)
    exported = store.export("ann")
    assert exported["profile"]["name"] == "Ann"
    ((run,),) = [exported["activities"]]
    ((stored,),) = [exported["sessions"]]
    assert run["session_id"] == stored["id"] and stored["ended"] is not None
    assert again.close() == 0


def test_a_session_started_before_the_outage_is_found_after_a_restart(
    store: ProfileStore, db: Path, reports: Reports
) -> None:
    service = service_of(store, reports)
    service.load("ann", NOW, wait_s=5.0)
    session = service.start_session("ann", NOW)
    assert service.writer.wait_idle(10.0)  # the session is stored, its id known here only
    with Lock(db):
        service.end_session(session, LATER)
        assert service.close() == 1
    again = service_of(store, reports)
    assert again.writer.wait_idle(10.0)
    assert store.export("ann")["sessions"][0]["ended"] is not None
    again.close()


def test_a_dropped_table_quarantines_that_write_and_the_rest_go_on(
    store: ProfileStore, db: Path, reports: Reports
) -> None:
    service = service_of(store, reports)
    service.load("ann", NOW, wait_s=5.0)
    with store.engine.begin() as connection:
        connection.execute(text("DROP TABLE feedback"))
    service.record_feedback("ann", "quiz", 0.5, NOW)
    service.update("ann", NOW, name="Ann")
    assert service.writer.wait_idle(10.0)
    assert store.get("ann").name == "Ann"
    ((key, line),) = reports
    assert key == "memory" and line.startswith("record_feedback refused: database error:")
    assert "no such table: feedback" in line and f"quarantined in {db}.quarantine" in line
    (entry,) = [json.loads(x) for x in Path(f"{db}.quarantine").read_text().splitlines()]
    assert entry["op"] == "record_feedback" and entry["args"][:3] == ["ann", "quiz", 0.5]
    assert service.close() == 0


def test_a_value_the_store_refuses_is_quarantined_not_queued(
    store: ProfileStore, reports: Reports
) -> None:
    service = service_of(store, reports, threaded=False)
    service.load("ann", NOW)
    service.record_feedback("ann", "quiz", 7.0, NOW)
    assert service.pending_writes == 0
    ((key, line),) = reports
    assert key == "memory" and line.startswith("record_feedback refused: score:")
    assert len(service.writer.quarantine.entries()) == 1
    service.close()


@pytest.fixture
def postgres_url() -> Iterator[str]:
    if not POSTGRES_URL:
        pytest.skip("DMS_TEST_POSTGRES_URL is not set")
    with fresh_schema() as url:
        yield url


def test_postgres_refusing_a_nul_byte_blocks_no_other_write(
    postgres_url: str, tmp_path: Path, reports: Reports
) -> None:
    store = ProfileStore(postgres_url)
    service = service_of(
        store,
        reports,
        spool_path=tmp_path / "pg.spool",
        quarantine_path=tmp_path / "pg.quarantine",
    )
    try:
        for user in ("ann", "bob"):
            assert service.load(user, NOW, wait_s=5.0) is not None
        service.record_answer("ann", "favorite_room", "kitchen\x00", NOW)
        for n in range(5):
            service.record_feedback("bob", "quiz", n / 4, NOW)
        service.update("ann", NOW, name="Ann")
        assert service.writer.wait_idle(10.0)
        assert store.export("bob")["profile"]["scores"]["quiz"]["feedback_count"] == 5
        assert store.get("ann").name == "Ann" and store.export("ann")["answers"] == []
        ((key, line),) = reports
        assert key == "memory" and line.startswith("record_answer refused: database error:")
        assert "NUL" in line
        (entry,) = service.writer.quarantine.entries()
        assert entry["args"][2] == "kitchen\x00"
        assert service.close() == 0
    finally:
        store.close()
