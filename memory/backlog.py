"""A writer's backlog: writes waiting for the database, kept wherever they can be.

The writes wait in memory, in order, and are mirrored, fsync'd, in a spool file
(:mod:`memory.spool`'s format) so that a kill -9 or a power cut loses none. The spool
file can fail too: the disk beside the database fills up, turns read-only, or gives I/O
errors. Then the whole backlog is written to the next place that takes it: the spool
beside the database, else the one in ``[storage] spool_dir`` (another filesystem). When
no place takes it, the writes stay in memory only, up to ``memory_bound``; past it new
writes are dropped and counted. Each change of place is one line in :meth:`Backlog.news`
(the writer reports them: the log and ``dms/errors``), never one per write. A backlog
that is not on disk tries a place again now and then (:meth:`Backlog.retry`, with a
doubling wait), so when space returns everything waiting is on disk again. A backlog
made without a path (a process that keeps no spool: the command line) is memory only.

A full disk is the usual reason the database fails, and then its spool beside it cannot
be written either. So the backlog keeps :data:`RESERVE_BYTES` allocated beside the spool
while nothing waits, and frees it for the spool when no place takes the writes: the
writes that wait are on disk, and survive an exit, without ``[storage] spool_dir``.

No method raises on a disk error: the backlog is the writer's last line, and the writer
must never die of it. Not thread-safe: the writer serializes calls.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import time
from collections import deque
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

from dms.kernel.files import open_nofollow
from memory.errors import one_line
from memory.spool import MAX_BINDS, open_spool, write_spool

log = logging.getLogger(__name__)

MEMORY_BOUND = 10_000
"""Writes kept in memory when no spool file can be written; past it new ones are dropped
(the default of ``[storage] memory_bound``)."""
RETRY_S = (0.25, 8.0)
"""First and longest wait between two tries to put a backlog kept in memory on disk."""
RESERVE_BYTES = 4 << 20
"""Disk space kept beside the spool for it (a ``.reserve`` file), given up to the spool
when the disk is full: room for more writes than the memory bound holds (a profile
write is a few hundred bytes), so that a full disk loses none at exit by default."""


class Backlog:
    """Pending writes in order, in memory and in the first spool file that takes them."""

    def __init__(
        self,
        path: Path | None,
        spare_dir: Path | None = None,
        memory_bound: int = MEMORY_BOUND,
        check: Callable[[dict[str, Any]], bool] | None = None,
        clock: Callable[[], float] = time.monotonic,
        reserve: int = RESERVE_BYTES,
    ) -> None:
        """``path``: the spool beside the database; ``spare_dir``: a folder on another
        filesystem for a spool of the same name when ``path`` cannot be written.
        ``check``: whether a spooled entry read back is a write (the others are kept
        aside in a ``.bad`` file). ``clock``: seconds, for the waits between retries.
        ``reserve``: bytes kept beside ``path`` for the spool (0: none)."""
        self.path = path
        self.places = [] if path is None else [path]
        self._reserve = None if path is None or reserve <= 0 else Reserve(path, reserve)
        if path is not None and spare_dir is not None:
            self.places.append(spare_dir / path.name)
        self.memory_bound = memory_bound
        self.pending: deque[dict[str, Any]] = deque()
        """Entries not yet in the database, oldest first."""
        self.binds: dict[str, int] = {}
        self.lost = 0
        """Writes dropped at the memory bound by this process."""
        self._bound_told = False
        self.damaged: list[tuple[Path, int, Path | None]] = []
        """(spool file, unreadable lines, the ``.bad`` file keeping them or None when it
        could not be written) found at start."""
        self._clock = clock
        self._file: IO[Any] | None = None
        self._at: Path | None = None
        self._on_disk = True
        """Every pending entry is in the file at :attr:`_at` (or nothing is pending)."""
        self._failures: dict[Path, str] = {}
        self._retry_at = 0.0
        self._wait = RETRY_S[0]
        self._news: list[str] = []
        self._said: Path | None = path
        """Where the last report said the backlog is (None: memory): one line a change;
        a backlog without a path says nothing of memory."""
        self._unreadable: set[Path] = set()
        self._read_places(check)
        if self.pending:
            log.warning("replaying %d spooled write(s) from %s", len(self.pending), self.where)
            self._settle()
        else:
            self._remove_files()
            self._keep_reserve()

    # ------------------------------------------------------------------ state

    def __len__(self) -> int:
        return len(self.pending)

    @property
    def on_disk(self) -> bool:
        """Every waiting write is in a spool file (true when none waits)."""
        return self._on_disk

    @property
    def where(self) -> Path | str:
        """The spool file holding the backlog now (the first place when none does)."""
        return self._at or self.path or "memory"

    def news(self) -> list[str]:
        """The report lines since the last call (a change of place, the bound reached)."""
        lines, self._news = self._news, []
        return lines

    # ------------------------------------------------------------------ changes

    def append(self, entries: list[dict[str, Any]], binds: dict[str, int]) -> None:
        """Add ``entries`` at the end: in the spool file before returning when one takes them.

        ``binds``: keys already bound in the database that the entries may name; written
        first when the backlog starts, so a restart can resolve them.
        """
        if not entries:
            return
        if not self._on_disk and len(self.pending) + len(entries) > self.memory_bound:
            room = max(0, self.memory_bound - len(self.pending))
            dropped = len(entries) - room
            if not self._bound_told:
                self._bound_told = True
                self._tell(
                    f"the memory bound of {self.memory_bound} write(s) is reached and no "
                    "spool can be written: new writes are dropped until one can"
                )
            self.lost += dropped
            entries = entries[:room]
            if not entries:
                return
        starting = not self.pending
        if starting:
            for key, value in list(binds.items())[-MAX_BINDS:]:
                self._remember(key, value)
        self.pending.extend(entries)
        if starting:
            self._on_disk = False
            self._settle()
        elif self._file is not None:
            self._write(entries)
        else:
            self.retry()

    def prepend(self, entries: list[dict[str, Any]], binds: dict[str, int]) -> None:
        """Put ``entries`` before the pending ones (they were taken earlier); rewrites the file."""
        if not entries:
            return
        for key, value in binds.items():
            self._remember(key, value)
        self.pending.extendleft(reversed(entries))
        self._on_disk = False
        self._settle()

    def bind(self, key: str, value: int) -> None:
        """Remember that ``key`` is ``value`` in the database (durably while writes wait)."""
        self._remember(key, value)
        if self.pending and self._file is not None:
            self._write([{"bind": key, "id": value}])

    def done(self, count: int) -> None:
        """The first ``count`` pending entries are in the database; no file once none waits."""
        count = min(count, len(self.pending))
        if count <= 0:
            return
        for _ in range(count):
            self.pending.popleft()
        if not self.pending:
            self._close_file()
            self.binds.clear()
            self._remove_files()
            if self._bound_told:
                self._tell(
                    f"every waiting write is in the database; {self.lost} write(s) "
                    "were dropped at the memory bound before"
                )
            self._bound_told = False
            self._on_disk = True
            self._failures.clear()
            self._said = self.path
            self._keep_reserve()
        elif self._file is not None:
            self._write([{"done": count}])
        else:
            self.retry()

    def retry(self) -> None:
        """A backlog kept in memory: try the spool files again when the wait is over."""
        if not self._on_disk and self._clock() >= self._retry_at:
            self._settle()

    def close(self) -> None:
        """Try every place once more for what waits, then close the file."""
        if self.pending and not self._on_disk:
            self._settle()
        self._close_file()
        if not self.pending:
            self._remove_files()

    # ------------------------------------------------------------------ the files

    def _read_places(self, check: Callable[[dict[str, Any]], bool] | None) -> None:
        """Load what earlier runs left in the places, the least recently written first."""
        found: list[tuple[float, Path]] = []
        for place in self.places:
            try:
                found.append((place.stat().st_mtime, place))
            except FileNotFoundError:
                continue
            except OSError as error:
                self._cannot_read(place, error)
        for _, place in sorted(found):
            try:
                contents = open_spool(place, check)
            except OSError as error:
                self._cannot_read(place, error)
                continue
            self.pending.extend(contents.pending)
            for key, value in contents.binds.items():
                self._remember(key, value)
            if contents.bad:
                self.damaged.append((place, len(contents.bad), contents.kept))

    def _cannot_read(self, place: Path, error: OSError) -> None:
        """A spool that cannot be read is left alone: never overwritten, never removed."""
        self._unreadable.add(place)
        self.places = [p for p in self.places if p != place]
        self._tell(f"cannot read the spool {place} ({one_line(error)}); it is left as it is")

    def _settle(self) -> None:
        """Write the whole backlog to the first place that takes it, with the space kept
        for it when the disk is full; memory when none does."""
        self._close_file()
        if self._try_places():
            return
        if self._reserve is not None and self._reserve.release():
            self._tell(
                f"no spool can be written ({self._failed_places()}): the "
                f"{self._reserve.size >> 20} MiB kept for it in {self._reserve.path} "
                "are given to it"
            )
            self._failures.clear()
            if self._try_places():
                return
        self._at, self._on_disk = None, False
        self._retry_at = self._clock() + self._wait
        self._wait = min(self._wait * 2, RETRY_S[1])
        if self._said is not None:
            self._said = None
            self._tell(
                f"no spool can be written ({self._failed_places()}): "
                f"{len(self.pending)} waiting write(s) are kept in memory only "
                f"(at most {self.memory_bound}) until a spool can be written"
            )

    def _try_places(self) -> bool:
        """Write the whole backlog to the first place that takes it; whether one did."""
        for place in self.places:
            try:
                write_spool(place, self.pending, self.binds)
                self._file = open_nofollow(place, "a")
            except OSError as error:
                self._close_file()
                self._failures[place] = one_line(error)
                continue
            self._at, self._on_disk = place, True
            self._wait = RETRY_S[0]
            self._remove_files(keep=place)
            if self._said != place:
                self._said = place
                self._tell(
                    f"{len(self.pending)} waiting write(s) are spooled to {place} "
                    f"({self._failed_places(but=place) or 'it can be written again'})"
                )
            self._failures.pop(place, None)
            return True
        return False

    def _write(self, lines: list[dict[str, Any]]) -> None:
        """Append to the open file; a failure moves the backlog to the next place."""
        assert self._file is not None
        try:
            self._file.write("".join(json.dumps(line) + "\n" for line in lines))
            self._file.flush()
            os.fsync(self._file.fileno())
        except (OSError, ValueError) as error:
            if self._at is not None:
                self._failures[self._at] = one_line(error)
            self._on_disk = False
            self._settle()

    def _close_file(self) -> None:
        if self._file is not None:
            with contextlib.suppress(OSError, ValueError):
                self._file.close()
            self._file = None

    def _remove_files(self, keep: Path | None = None) -> None:
        """Remove the spool files that no longer hold the backlog (stale copies)."""
        for place in self.places:
            if place == keep or place in self._unreadable:
                continue
            try:
                place.unlink(missing_ok=True)
            except OSError as error:
                log.warning("cannot remove the old spool %s: %s", place, error)
        if keep is None:
            self._at = None

    def _keep_reserve(self) -> None:
        """Nothing waits: allocate the space for the next outage's spool again (one line
        when it cannot be, and one when it can again)."""
        if self._reserve is None:
            return
        news = self._reserve.keep()
        if news is not None:
            self._tell(news)

    def _remember(self, key: str, value: int) -> None:
        self.binds[key] = value
        if len(self.binds) > MAX_BINDS:
            del self.binds[next(iter(self.binds))]

    def _failed_places(self, but: Path | None = None) -> str:
        return "; ".join(f"{p}: {e}" for p, e in self._failures.items() if p != but)

    def _tell(self, line: str) -> None:
        """A line for the owner to report (the daemon logs and publishes it)."""
        self._news.append(line)


class Reserve:
    """Disk space kept for a spool: a file of ``size`` allocated bytes beside it."""

    def __init__(self, spool: Path, size: int) -> None:
        self.path = spool.with_name(spool.name + ".reserve")
        self.size = size
        self._missing: str | None = None
        """Why the space could not be kept, while it cannot (said once)."""

    def keep(self) -> str | None:
        """Allocate the space unless it is; a line to report when that fails for the
        first time, or succeeds again after a failure."""
        try:
            if self.path.is_symlink() or not self.path.is_file():
                with open_nofollow(self.path, "wb") as out:
                    os.posix_fallocate(out.fileno(), 0, self.size)
                    os.fsync(out.fileno())
        except OSError as error:
            with contextlib.suppress(OSError):
                self.path.unlink(missing_ok=True)
            if self._missing is None:
                self._missing = one_line(error)
                return (
                    f"cannot keep {self.size >> 20} MiB for the spool in {self.path} "
                    f"({self._missing}): on a full disk, waiting writes would be kept in "
                    "memory only"
                )
            return None
        if self._missing is not None:
            self._missing = None
            return f"{self.size >> 20} MiB are kept for the spool in {self.path} again"
        return None

    def release(self) -> bool:
        """Free the space for the spool; whether there was any."""
        try:
            self.path.unlink()
        except FileNotFoundError:
            return False
        except OSError as error:
            log.warning("cannot free the space kept for the spool (%s): %s", self.path, error)
            return False
        return True
