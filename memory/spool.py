"""Durable local files for writes the database did not take: the spool and the quarantine.

:class:`Spool` is an append-only journal of writes that wait for the database (it is
locked, or gone): one JSON object per line, ``fsync``'d before :meth:`Spool.append`
returns, so a write in it survives a kill -9, a power cut and a clean exit, and is
replayed in order at the next start. Replayed writes are marked done by a line
``{"done": n}`` (the first ``n`` pending entries are done); the file is emptied when
nothing is pending and compacted when it is reopened. A ``{"bind": key, "id": n}`` line
remembers which database id a client-side key got (a session started before the
outage), so that spooled writes naming the key still find it after a restart.

:class:`Quarantine` keeps, one JSON line each, the writes the database refused for good
(a constraint, a value it cannot store, a missing table), so none is lost silently.

The files hold JSON-able dicts; what a write means is the caller's business.
"""

from __future__ import annotations

import json
import logging
import os
from collections import deque
from pathlib import Path
from typing import Any

log = logging.getLogger(__name__)

MAX_BINDS = 1000
"""Keys remembered for spooled writes; a session older than this many is long closed."""


def _fsync_dir(path: Path) -> None:
    """Make a new or renamed file's directory entry durable too."""
    try:
        fd = os.open(path.parent, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


class Spool:
    """An append-only, fsync'd journal of pending writes, replayed in order.

    Not thread-safe: its owner (the storage writer) serializes calls.
    """

    def __init__(self, path: Path) -> None:
        self.path = path
        self.pending: deque[dict[str, Any]] = deque()
        """Entries not yet done, oldest first."""
        self.binds: dict[str, int] = {}
        self.damaged_lines = 0
        """Lines that could not be read back (a torn last line after a crash)."""
        if path.exists():
            self._read()
            self._rewrite()
        self._file = path.open("a", encoding="utf-8")

    def _read(self) -> None:
        with self.path.open(encoding="utf-8") as lines:
            for line in lines:
                try:
                    entry = json.loads(line)
                except json.JSONDecodeError:
                    self.damaged_lines += 1  # only a torn last line: appends are whole lines
                    continue
                if not isinstance(entry, dict):
                    self.damaged_lines += 1
                elif "done" in entry:
                    for _ in range(min(int(entry["done"]), len(self.pending))):
                        self.pending.popleft()
                elif "bind" in entry:
                    self._remember(str(entry["bind"]), int(entry["id"]))
                else:
                    self.pending.append(entry)
        if self.damaged_lines:
            log.warning("%s: %d unreadable line(s) skipped", self.path, self.damaged_lines)

    def _remember(self, key: str, value: int) -> None:
        self.binds[key] = value
        if len(self.binds) > MAX_BINDS:
            del self.binds[next(iter(self.binds))]

    def _rewrite(self) -> None:
        """Write the pending entries (and binds) to a new file and swap it in atomically."""
        if not self.pending:
            self.binds.clear()
        temporary = self.path.with_name(self.path.name + ".tmp")
        with temporary.open("w", encoding="utf-8") as out:
            for key, value in self.binds.items():
                out.write(json.dumps({"bind": key, "id": value}) + "\n")
            for entry in self.pending:
                out.write(json.dumps(entry) + "\n")
            out.flush()
            os.fsync(out.fileno())
        os.replace(temporary, self.path)
        _fsync_dir(self.path)

    def _write(self, entries: list[dict[str, Any]]) -> None:
        self._file.write("".join(json.dumps(e) + "\n" for e in entries))
        self._file.flush()
        os.fsync(self._file.fileno())

    def __len__(self) -> int:
        return len(self.pending)

    def append(self, entries: list[dict[str, Any]], binds: dict[str, int] | None = None) -> None:
        """Add ``entries`` at the end, durably, before returning.

        ``binds``: keys already bound in the database that the entries may name; written
        first when the spool starts, so a restart can resolve them.
        """
        if not entries:
            return
        head: list[dict[str, Any]] = []
        if not self.pending and binds:
            for key, value in list(binds.items())[-MAX_BINDS:]:
                self._remember(key, value)
                head.append({"bind": key, "id": value})
        self._write(head + entries)
        self.pending.extend(entries)

    def prepend(self, entries: list[dict[str, Any]], binds: dict[str, int] | None = None) -> None:
        """Put ``entries`` before the pending ones (they were taken earlier); rewrites the file."""
        if not entries:
            return
        if not self.pending:
            self.append(entries, binds)
            return
        for key, value in (binds or {}).items():
            self._remember(key, value)
        self.pending.extendleft(reversed(entries))
        self._file.close()
        self._rewrite()
        self._file = self.path.open("a", encoding="utf-8")

    def bind(self, key: str, value: int) -> None:
        """Remember that ``key`` is ``value`` in the database (durably)."""
        self._remember(key, value)
        self._write([{"bind": key, "id": value}])

    def done(self, count: int) -> None:
        """The first ``count`` pending entries are in the database; empty the file at the end."""
        count = min(count, len(self.pending))
        if count <= 0:
            return
        for _ in range(count):
            self.pending.popleft()
        if self.pending:
            self._write([{"done": count}])
        else:
            self._file.close()
            self._rewrite()
            self._file = self.path.open("a", encoding="utf-8")

    def close(self) -> None:
        """Close the file; an empty spool leaves no file behind."""
        self._file.close()
        if not self.pending and self.path.exists() and self.path.stat().st_size == 0:
            self.path.unlink()


class Quarantine:
    """Writes the database refused for good, one fsync'd JSON line each, kept for a person."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.count = 0
        """Writes quarantined by this process."""

    def add(self, entry: dict[str, Any]) -> None:
        new = not self.path.exists()
        with self.path.open("a", encoding="utf-8") as out:
            out.write(json.dumps(entry) + "\n")
            out.flush()
            os.fsync(out.fileno())
        if new:
            _fsync_dir(self.path)
        self.count += 1

    def entries(self) -> list[dict[str, Any]]:
        """Everything quarantined so far (also by earlier runs), oldest first."""
        if not self.path.exists():
            return []
        out = []
        with self.path.open(encoding="utf-8") as lines:
            for line in lines:
                try:
                    out.append(json.loads(line))
                except json.JSONDecodeError:
                    continue
        return out
