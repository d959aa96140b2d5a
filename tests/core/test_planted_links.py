"""A symbolic link planted where one of the daemon's files goes is never followed: the
spool, its ``.bad`` file, its temporary file, the quarantine and the SQLite database
each refuse the link in one line, and the file it points to is left as it was."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from dms.kernel.files import LinkRefused
from dms.storage import Write
from memory.backlog import Backlog
from memory.db import make_engine
from memory.errors import ProfileError
from memory.spool import Quarantine, write_spool

GOOD = {"op": "update", "args": ["ann"], "kwargs": {}}
SECRET = b"root:x:0:0:precious\n"


@pytest.fixture
def outside(tmp_path: Path) -> Path:
    """A file outside the data folder that a planted link points to."""
    target = tmp_path / "elsewhere" / "passwd"
    target.parent.mkdir()
    target.write_bytes(SECRET)
    return target


@pytest.fixture
def data(tmp_path: Path) -> Path:
    folder = tmp_path / "data"
    folder.mkdir()
    return folder


def plant(link: Path, target: Path) -> None:
    link.symlink_to(target)


def test_a_link_as_the_spools_bad_file_is_not_appended_to(
    data: Path, outside: Path, caplog: pytest.LogCaptureFixture
) -> None:
    spool = data / "dms.db.mini.spool"
    spool.write_bytes(json.dumps(GOOD).encode() + b"\n" + b'{"torn": ')
    plant(data / "dms.db.mini.spool.bad", outside)
    backlog = Backlog(spool, check=Write.readable)
    assert list(backlog.pending) == [GOOD]
    assert backlog.damaged == [(spool, 1, None)]  # kept in the log, not through the link
    assert outside.read_bytes() == SECRET
    assert "is a symbolic link" in caplog.text
    backlog.close()


def test_a_link_as_the_spool_is_neither_read_nor_written(data: Path, outside: Path) -> None:
    spool = data / "dms.db.mini.spool"
    plant(spool, outside)
    backlog = Backlog(spool, check=Write.readable)
    assert not backlog.pending  # the target's lines were not read as writes
    news = backlog.news()
    assert any("is a symbolic link" in line and str(spool) in line for line in news), news
    backlog.append([GOOD], {})
    assert outside.read_bytes() == SECRET
    assert spool.is_symlink()  # left as it is, for a person to look at
    backlog.close()


def test_a_link_as_the_spools_temporary_file_is_replaced_not_followed(
    data: Path, outside: Path
) -> None:
    spool = data / "dms.db.mini.spool"
    plant(data / "dms.db.mini.spool.tmp", outside)
    write_spool(spool, [GOOD], {})
    assert outside.read_bytes() == SECRET
    assert [json.loads(line) for line in spool.read_text().splitlines()] == [GOOD]


def test_a_link_as_the_quarantine_is_refused(data: Path, outside: Path) -> None:
    path = data / "dms.db.mini.quarantine"
    plant(path, outside)
    with pytest.raises(LinkRefused, match="is a symbolic link"):
        Quarantine(path).add({"op": "update", "error": "refused"})
    assert outside.read_bytes() == SECRET


@pytest.mark.parametrize("end", ["", "-wal", "-shm", "-journal"])
def test_a_link_as_the_database_or_its_files_is_refused(
    data: Path, outside: Path, end: str
) -> None:
    db = data / "dms.db"
    plant(Path(f"{db}{end}"), outside)
    with pytest.raises(ProfileError, match=r"dms\.db.* is a symbolic link") as refused:
        make_engine(f"sqlite:///{db}")
    assert "\n" not in str(refused.value)
    assert outside.read_bytes() == SECRET
