"""The spool and the storage writer when files fail: a damaged spool never stops a start
(what cannot be read is kept aside in a ``.bad`` file), a spool that cannot be written
moves to the spare folder, then to memory up to its bound, the writer thread never dies,
and closing names what could not be kept."""

from __future__ import annotations

import errno
import json
import threading
from pathlib import Path
from typing import Any

import pytest

import memory.backlog
import memory.spool
from agenda.writer import readable
from dms.storage import StorageWriter, Write
from memory.backlog import Backlog
from memory.errors import StoreUnavailable
from memory.spool import read_spool

GOOD = {"op": "update", "args": ["ann"], "kwargs": {}}
TORN = [
    b'{"op": "update", "args": ["ann"], "kwa',  # a torn last line
    b'{"op": "update", "args": ["\xff\xfe"], "kwargs": {}}\n',  # not UTF-8
    b'{"done": "1x"}\n',
    b'{"bind": "k"}\n',
    b'{"op": "update"}\n',  # a write without its arguments
    b'["a", "list"]\n',
]


def write_lines(path: Path, *lines: bytes) -> None:
    path.write_bytes(b"".join(lines))


@pytest.mark.parametrize("bad", TORN)
def test_a_damaged_line_is_kept_aside_and_the_good_records_are_read(
    tmp_path: Path, bad: bytes
) -> None:
    path = tmp_path / "dms.db.mini.spool"
    good = json.dumps(GOOD).encode() + b"\n"
    write_lines(path, b'{"bind": "s1", "id": 7}\n', good, good, bad)
    backlog = Backlog(path, check=Write.readable)
    assert list(backlog.pending) == [GOOD, GOOD]
    assert backlog.binds == {"s1": 7}
    assert backlog.damaged == [(path, 1, tmp_path / "dms.db.mini.spool.bad")]
    kept = (tmp_path / "dms.db.mini.spool.bad").read_bytes()
    assert kept == (bad if bad.endswith(b"\n") else bad + b"\n")
    assert read_spool(path).bad == []  # the spool itself was rewritten clean
    backlog.close()


def test_the_agendas_journal_opens_a_torn_file_too(tmp_path: Path) -> None:
    path = tmp_path / "dms.db.agenda-spool"
    record = {
        "item_id": 1,
        "user_id": "ann",
        "kind": "reminder",
        "what": "pills",
        "outcome": "delivered",
        "first_us": 5,
        "last_us": 5,
        "count": 1,
        "recorded_us": 6,
        "reason": "",
        "cursor_us": None,
    }
    line = json.dumps(record).encode() + b"\n"
    write_lines(path, line, b'{"done": "1x"}\n', b'{"item_id": 2}\n', line, b"\xff")
    journal = Backlog(path, check=readable)
    assert list(journal.pending) == [record, record]
    assert journal.damaged == [(path, 3, tmp_path / "dms.db.agenda-spool.bad")]
    journal.close()
    kept = (tmp_path / "dms.db.agenda-spool.bad").read_bytes()
    assert kept == b'{"done": "1x"}\n{"item_id": 2}\n\xff\n'


def full_disk(broken: set[Path]) -> Any:
    """``write_spool`` that fails with ENOSPC for the paths in ``broken``."""
    real = memory.spool.write_spool

    def write_spool(path: Path, entries: Any, binds: dict[str, int]) -> None:
        if path in broken:
            raise OSError(errno.ENOSPC, "No space left on device")
        real(path, entries, binds)

    return write_spool


def test_a_full_disk_moves_the_backlog_to_the_spare_folder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    main, spare = tmp_path / "db" / "dms.spool", tmp_path / "spare"
    main.parent.mkdir()
    spare.mkdir()
    monkeypatch.setattr(memory.backlog, "write_spool", full_disk({main}))
    backlog = Backlog(main, spare)
    backlog.append([GOOD], {})
    (line,) = backlog.news()
    assert f"spooled to {spare / 'dms.spool'}" in line and "No space left" in line
    assert backlog.on_disk and not main.exists()
    backlog.append([GOOD], {})
    assert backlog.news() == []  # one line a change, never one a write
    assert len(read_spool(spare / "dms.spool").pending) == 2
    backlog.close()


def test_without_any_spool_writes_wait_in_memory_up_to_the_bound(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    main = tmp_path / "dms.spool"
    broken = {main}
    monkeypatch.setattr(memory.backlog, "write_spool", full_disk(broken))
    now = [0.0]
    backlog = Backlog(main, memory_bound=3, clock=lambda: now[0], reserve=0)
    backlog.append([GOOD] * 2, {})
    (in_memory,) = backlog.news()
    assert "kept in memory only" in in_memory and "at most 3" in in_memory
    backlog.append([GOOD] * 3, {})
    (bound,) = backlog.news()
    assert "memory bound of 3" in bound
    assert len(backlog) == 3 and backlog.lost == 2 and not backlog.on_disk
    broken.clear()  # space is back: the next retry puts the backlog on disk
    now[0] = 100.0
    backlog.retry()
    assert backlog.on_disk and len(read_spool(main).pending) == 3
    backlog.done(3)
    assert "2 write(s) were dropped" in backlog.news()[-1]
    assert not main.exists()


def test_a_full_disk_gives_the_space_kept_for_the_spool_to_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    main, kept = tmp_path / "dms.spool", tmp_path / "dms.spool.reserve"
    real = memory.backlog.write_spool

    def write_spool(path: Path, entries: Any, binds: dict[str, int]) -> None:
        if kept.exists():  # the disk is full until the kept space is freed
            raise OSError(errno.ENOSPC, "No space left on device")
        real(path, entries, binds)

    monkeypatch.setattr(memory.backlog, "write_spool", write_spool)
    backlog = Backlog(main, reserve=1 << 20)
    assert kept.stat().st_blocks * 512 >= 1 << 20  # allocated, not a sparse file
    backlog.append([GOOD] * 2, {})
    (given,) = backlog.news()
    assert "1 MiB kept for it" in given and str(kept) in given
    assert backlog.on_disk and len(read_spool(main).pending) == 2
    backlog.done(2)  # nothing waits: the space is kept again for the next outage
    assert kept.stat().st_size == 1 << 20 and not main.exists()
    backlog.close()


class FlakyStore:
    """``apply`` for a writer: records the writes; away while ``away`` is set."""

    def __init__(self) -> None:
        self.away = threading.Event()
        self.applied: list[Write] = []

    def __call__(self, write: Write) -> Any:
        if self.away.is_set():
            raise StoreUnavailable("database or disk is full")
        self.applied.append(write)
        return None


def make_writer(
    tmp_path: Path, store: FlakyStore, reports: list[str], **options: Any
) -> StorageWriter:
    return StorageWriter(
        store,
        tmp_path / "dms.spool",
        tmp_path / "dms.quarantine",
        lambda _key, line: reports.append(line),
        **options,
    )


def test_the_writer_survives_a_full_disk_and_writes_everything_when_space_returns(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    broken = {tmp_path / "dms.spool"}
    monkeypatch.setattr(memory.backlog, "write_spool", full_disk(broken))
    store, reports = FlakyStore(), list[str]()
    writer = make_writer(tmp_path, store, reports)
    writer.start()
    store.away.set()
    for n in range(20):
        writer.submit(Write("update", (f"user{n}",)))
    writer.submit(Write("update", ("last",)))
    assert not writer.wait_idle(0.5)
    health = writer.health
    assert health.status == "degraded" and health.pending == 21
    assert "disk is full" in (health.reason or "") and "in memory" in (health.reason or "")
    assert sum("failed, will retry" in line for line in reports) == 1
    assert sum("kept in memory only" in line for line in reports) == 1
    broken.clear()
    store.away.clear()
    assert writer.wait_idle(30.0)
    assert [w.args[0] for w in store.applied] == [*(f"user{n}" for n in range(20)), "last"]
    assert writer.health.status == "ok"
    assert writer.close() == 0


def test_close_keeps_the_queue_without_the_thread_or_names_what_is_lost(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    store, reports = FlakyStore(), list[str]()
    writer = make_writer(tmp_path, store, reports)  # its thread never started
    for n in range(3):
        writer.submit(Write("update", (f"user{n}",)))
    assert writer.close() == 3
    assert len(read_spool(tmp_path / "dms.spool").pending) == 3
    assert reports[-1].startswith("3 write(s) still spooled in")

    monkeypatch.setattr(memory.backlog, "write_spool", full_disk({tmp_path / "elsewhere.spool"}))
    lost: list[str] = []
    writer = StorageWriter(
        store, tmp_path / "elsewhere.spool", tmp_path / "q", lambda _k, line: lost.append(line)
    )
    writer.submit(Write("update", ("ann",)))
    assert writer.close() == 1
    assert lost[-1].startswith("1 write(s) could not be kept")


def test_an_unforeseen_failure_does_not_kill_the_writer(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    store, reports = FlakyStore(), list[str]()
    writer = make_writer(tmp_path, store, reports)
    writer.start()
    real = Backlog.prepend
    calls = [0]

    def prepend(self: Backlog, entries: list[dict[str, Any]], binds: dict[str, int]) -> None:
        calls[0] += 1
        if calls[0] == 1:
            raise RuntimeError("a bug in the spool")
        real(self, entries, binds)

    monkeypatch.setattr(Backlog, "prepend", prepend)
    store.away.set()
    writer.submit(Write("update", ("ann",)))
    assert not writer.wait_idle(0.5)
    store.away.clear()
    assert writer.wait_idle(30.0)
    assert writer._thread is not None and writer._thread.is_alive()
    assert [w.args[0] for w in store.applied] == ["ann"]
    assert sum("the storage writer failed" in line for line in reports) == 1
    writer.close()


def test_a_deleted_database_file_is_noticed_and_its_writes_spooled(tmp_path: Path) -> None:
    database = tmp_path / "dms.db"
    opened = database.open("wb")  # held open, as SQLite does: its inode stays its own
    store, reports = FlakyStore(), list[str]()
    writer = make_writer(tmp_path, store, reports, database_file=database)
    writer.start()
    writer.submit(Write("update", ("ann",)))
    assert writer.wait_idle(10.0)
    database.unlink()
    database.write_bytes(b"")  # another file at its path
    writer.submit(Write("update", ("bob",)))
    assert not writer.wait_idle(0.5)
    assert [w.args[0] for w in store.applied] == ["ann"]
    (line,) = [line for line in reports if "failed, will retry" in line]
    assert f"the database file {database} was replaced" in line
    assert writer.health.status == "degraded"
    assert writer.close() == 1
    assert read_spool(tmp_path / "dms.spool").pending[0]["args"] == ["bob"]
    opened.close()
