"""Hot reload: notice saved behavior and rules files and ask for a reload.

A thread of its own polls a cheap fingerprint of the files (the name, size, mtime_ns and
inode of every ``*.yaml`` of the behaviors folder and of each rules file) every
``[behaviors] watch_s`` seconds, and asks the reloader (:mod:`dms.reloader`) for a
reload when it changed. The tick thread never stats a file, and a stop is prompt: the
thread waits on an event between polls.

Only the folder's own ``*.yaml`` files count, as the behavior loader reads them: the
``drafts/`` subfolder, where the studio writes a behavior that does not load, is not
watched.

A change is acted on once it has held still for one poll, so a saved file is in force
within two periods. A file being written when a poll sees it has a new fingerprint at
the next poll, which waits for it; if a reload still reads a file half-written (a write
slower than a poll), the next poll sees the final fingerprint and reloads again, so the
final version wins. A change that does not verify goes the way of every reload: the
running version stays in force and the problem is reported once on ``dms/errors``
(the next polls see the same fingerprint; a fix is a new one).

Each reload, whatever asked for it (SIGHUP, ``reload_rules``, this watch), first calls
:meth:`FileWatch.mark`: the files as they are then are the ones it reads, so a change a
SIGHUP already put in force is not reloaded again by the watch.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable, Sequence
from pathlib import Path

log = logging.getLogger(__name__)

Fingerprint = tuple[tuple[str, int, int, int], ...]
"""``(path, size, mtime_ns, inode)`` of each watched file; ``-1`` for a missing one. The
inode tells an atomic save (a rename) of a file of the same size from the old one on a
filesystem whose mtime is coarse."""

MISSING = (-1, -1, -1)


def fingerprint(folder: Path | None, files: Sequence[Path]) -> Fingerprint:
    """The folder's ``*.yaml`` files (not its subfolders) and ``files``, as they are now."""
    paths = sorted(folder.glob("*.yaml")) if folder is not None else []
    entries = []
    for path in [*paths, *files]:
        try:
            stat = path.stat()
        except OSError:  # gone, or unreadable: its return is a change
            entries.append((str(path), *MISSING))
            continue
        entries.append((str(path), stat.st_size, stat.st_mtime_ns, stat.st_ino))
    return tuple(entries)


class FileWatch:
    """Polls :func:`fingerprint` on its own thread and calls ``on_change`` once for each
    change that held still for one poll.

    It is off (no thread, no look at any file) when ``period_s`` is 0 or there is nothing
    to watch (the shipped behaviors and no rules files).
    """

    def __init__(
        self,
        folder: Path | None,
        files: Sequence[Path],
        on_change: Callable[[], None],
        period_s: float,
    ) -> None:
        """Take the first fingerprint now: make the watch before the files are loaded, so
        that a change made while they load is seen."""
        self._folder = folder
        self._files = tuple(files)
        self._on_change = on_change
        self.period_s = period_s
        self.on = period_s > 0 and (folder is not None or bool(self._files))
        self._lock = threading.Lock()
        self._seen = fingerprint(folder, self._files) if self.on else ()
        """The files as the last reload (or the start) found them."""
        self._pending: Fingerprint | None = None
        """A new fingerprint seen once, waiting for the next poll to hold still."""
        self._stopped = threading.Event()
        self._thread = threading.Thread(target=self._run, name="dms-watch", daemon=True)

    def mark(self) -> None:
        """A reload is about to read the files: what they are now is what it reads."""
        if not self.on:
            return
        with self._lock:
            self._seen = fingerprint(self._folder, self._files)
            self._pending = None

    def poll(self) -> bool:
        """One look at the files; True when it asked for a reload."""
        with self._lock:
            now = fingerprint(self._folder, self._files)
            if now == self._seen:
                self._pending = None
                return False
            if now != self._pending:  # new, or still changing: wait for one more poll
                self._pending = now
                return False
            self._seen, self._pending = now, None
        log.info("behavior or rules files changed: reloading")
        self._on_change()
        return True

    def start(self) -> None:
        if self.on:
            self._thread.start()

    def _run(self) -> None:
        while not self._stopped.wait(self.period_s):
            try:
                self.poll()
            except Exception:  # a failing look must not end the watch
                log.exception("watching the behavior and rules files failed")

    def stop(self, timeout_s: float = 1.0) -> None:
        """Stop polling; a poll under way (a hung filesystem) is not waited for past
        ``timeout_s`` (the thread is a daemon thread, dropped at exit)."""
        self._stopped.set()
        if self._thread.is_alive():
            self._thread.join(timeout_s)
