"""Whether the SQLite file a process opened is still the one at its path.

SQLite keeps writing into a file deleted or replaced under it (a restore copied over it,
a cleanup script), and what it writes there is lost at the exit. A writer asks
:meth:`FileWatch.check` before it writes, so that such writes wait in its spool instead,
and the outage is reported like any other.
"""

from __future__ import annotations

import os
from pathlib import Path

from sqlalchemy.engine import make_url

from memory.db import as_url
from memory.errors import StoreUnavailable

CHECK_FILE_EVERY_S = 0.1
"""How often a run of writes looks at the file (and always before the first write after
a pause: :meth:`FileWatch.look_next`)."""


def sqlite_file(url: str) -> Path | None:
    """The file of a SQLite database URL; None for a server or an in-memory database."""
    parsed = make_url(as_url(url))
    if parsed.get_backend_name() != "sqlite" or parsed.database in (None, "", ":memory:"):
        return None
    return Path(parsed.database).expanduser().absolute()


def _identity(path: Path) -> tuple[int, int] | None:
    """The device and inode of the file at ``path``; None when there is none."""
    try:
        status = os.stat(path)
    except OSError:
        return None
    return status.st_dev, status.st_ino


class FileWatch:
    """The SQLite file at ``path`` as it was when the process opened it."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._identity = _identity(path)
        self._checked_at = -CHECK_FILE_EVERY_S

    def look_next(self) -> None:
        """Look at the file before the next write, however soon it comes."""
        self._checked_at = -CHECK_FILE_EVERY_S

    def check(self, now: float) -> None:
        """Raise StoreUnavailable when the file is no longer the one opened (looked at
        most every :data:`CHECK_FILE_EVERY_S` of ``now``, in seconds)."""
        if self._identity is None or now - self._checked_at < CHECK_FILE_EVERY_S:
            return
        self._checked_at = now
        current = _identity(self.path)
        if current == self._identity:
            return
        self.look_next()  # until it is back, look every time
        what = "deleted" if current is None else "replaced by another file"
        raise StoreUnavailable(
            f"the database file {self.path} was {what} while the daemon runs; "
            "nothing is written into the old one, a restart opens the file now there"
        )
