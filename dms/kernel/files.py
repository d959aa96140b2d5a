"""The daemon's own files, opened without following a symbolic link.

The daemon may run as root beside folders that others can write. A link planted where
one of its files goes (a spool, the spool's ``.bad`` file, a quarantine, the database)
would make it read, append to or overwrite any file on the machine. So every file it
writes in its data, spool and secure folders is opened here with ``O_NOFOLLOW``: a link
is refused with :class:`LinkRefused`, an ``OSError``, which the callers already treat as
a file that cannot be written (a spool moves to its next place, a quarantined write
goes to the log) and report in one line.
"""

from __future__ import annotations

import errno
import os
from pathlib import Path
from typing import IO, Any, Literal

Mode = Literal["rb", "ab", "a", "wb", "w"]

_FLAGS: dict[str, int] = {
    "rb": os.O_RDONLY,
    "ab": os.O_WRONLY | os.O_CREAT | os.O_APPEND,
    "a": os.O_WRONLY | os.O_CREAT | os.O_APPEND,
    "wb": os.O_WRONLY | os.O_CREAT | os.O_EXCL,
    "w": os.O_WRONLY | os.O_CREAT | os.O_EXCL,
}


class LinkRefused(OSError):
    """A file the daemon writes is a symbolic link: it is never followed."""

    def __init__(self, path: Path) -> None:
        super().__init__(errno.ELOOP, "is a symbolic link", str(path))
        self.path = path

    def __str__(self) -> str:
        return (
            f"{self.path} is a symbolic link: dms never reads or writes through one "
            "(remove the link; dms makes the file itself)"
        )


def open_nofollow(path: Path, mode: Mode) -> IO[Any]:
    """Open ``path`` without following a link: ``rb`` to read, ``a``/``ab`` to append
    (made when missing), ``w``/``wb`` to make a new file (one left over, or a link, is
    removed first: the link itself, never what it points to).

    Raises :class:`LinkRefused` when ``path`` is a link, OSError when it cannot be opened.
    """
    if mode in ("w", "wb"):
        path.unlink(missing_ok=True)
    try:
        fd = os.open(path, _FLAGS[mode] | os.O_NOFOLLOW | os.O_CLOEXEC, 0o644)
    except OSError as error:
        if error.errno == errno.ELOOP:
            raise LinkRefused(path) from None
        raise
    if mode in ("a", "w"):
        return os.fdopen(fd, mode, encoding="utf-8")
    return os.fdopen(fd, mode)


def refuse_link(path: Path) -> None:
    """Raise :class:`LinkRefused` when ``path`` is a link (for a file another library
    opens, such as SQLite's database and its ``-wal``, ``-shm`` and ``-journal`` files)."""
    if path.is_symlink():
        raise LinkRefused(path)
