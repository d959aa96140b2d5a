"""Durable local files for writes the database did not take: the spool and the quarantine.

A spool is an append-only file of writes that wait for the database (it is locked, or
gone): one JSON object per line, ``fsync``'d, so a write in it survives a kill -9, a
power cut and a clean exit, and is replayed in order at the next start
(:class:`memory.backlog.Backlog` keeps it). Replayed writes are marked done by a line
``{"done": n}`` (the first ``n`` pending entries are done); :func:`write_spool` compacts
it. A ``{"bind": key, "id": n}`` line remembers which database id a client-side key got
(a session started before the outage), so that spooled writes naming the key still find
it after a restart.

:func:`read_spool` reads such a file for every owner (the profile store's spool, the
agenda's journal). What it cannot read (a torn last line, bytes that are not UTF-8, a record
missing its keys or with values of the wrong type) is skipped and kept aside, byte for
byte, in a ``.bad`` file beside it (:func:`keep_aside`): a damaged file never stops a
start, and nothing in it is thrown away.

:class:`Quarantine` keeps, one JSON line each, the writes the database refused for good
(a constraint, a value it cannot store, a missing table), so none is lost silently.

The files hold JSON-able dicts; what a write means is the caller's business.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from dms.kernel.files import open_nofollow

log = logging.getLogger(__name__)

MAX_BINDS = 1000
"""Keys remembered for spooled writes; a session older than this many is long closed."""


def fsync_dir(path: Path) -> None:
    """Make a new or renamed file's directory entry durable too."""
    try:
        fd = os.open(path.parent, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


@dataclass
class SpoolContents:
    """What :func:`read_spool` found in a spool file."""

    pending: deque[dict[str, Any]] = field(default_factory=deque)
    """Entries not yet done, oldest first."""
    binds: dict[str, int] = field(default_factory=dict)
    bad: list[bytes] = field(default_factory=list)
    """Lines that could not be read, as they were in the file."""
    kept: Path | None = None
    """The ``.bad`` file that holds them (:func:`open_spool`); None when it could not be
    written (they are in the log)."""


def _remember(binds: dict[str, int], key: str, value: int) -> None:
    binds[key] = value
    if len(binds) > MAX_BINDS:
        del binds[next(iter(binds))]


def read_spool(path: Path, check: Callable[[dict[str, Any]], bool] | None = None) -> SpoolContents:
    """The pending entries and binds of the spool file at ``path``.

    ``check`` tells whether an entry is one its owner can use (its keys, their types); a
    line that is not a JSON object in UTF-8, a ``done`` or ``bind`` line of the wrong
    shape, or an entry ``check`` refuses goes to :attr:`SpoolContents.bad`. Raises
    OSError only when the file cannot be read at all.
    """
    contents = SpoolContents()
    with open_nofollow(path, "rb") as lines:
        for raw in lines:
            if not raw.strip():
                continue
            try:
                entry = json.loads(raw.decode("utf-8"))
            except ValueError:  # a torn line, or bytes that are not UTF-8
                contents.bad.append(raw)
                continue
            if not isinstance(entry, dict):
                contents.bad.append(raw)
            elif "done" in entry:
                count = entry["done"]
                if not isinstance(count, int) or isinstance(count, bool) or count < 0:
                    contents.bad.append(raw)
                    continue
                for _ in range(min(count, len(contents.pending))):
                    contents.pending.popleft()
            elif "bind" in entry:
                key, value = entry["bind"], entry.get("id")
                if (
                    not isinstance(key, str)
                    or not isinstance(value, int)
                    or isinstance(value, bool)
                ):
                    contents.bad.append(raw)
                    continue
                _remember(contents.binds, key, value)
            elif check is None or check(entry):
                contents.pending.append(entry)
            else:
                contents.bad.append(raw)
    return contents


def bad_file(path: Path) -> Path:
    """Where the unreadable lines of the spool at ``path`` are kept: ``<path>.bad``."""
    return path.with_name(path.name + ".bad")


def keep_aside(path: Path, lines: Iterable[bytes]) -> Path:
    """Append ``lines`` (unreadable lines of the spool at ``path``) to its ``.bad`` file,
    fsync'd; returns that file. Raises OSError when it cannot be written."""
    bad = bad_file(path)
    new = not bad.exists()
    with open_nofollow(bad, "ab") as out:
        out.write(b"".join(line if line.endswith(b"\n") else line + b"\n" for line in lines))
        out.flush()
        os.fsync(out.fileno())
    if new:
        fsync_dir(bad)
    return bad


def write_spool(path: Path, entries: Iterable[dict[str, Any]], binds: dict[str, int]) -> None:
    """Write ``binds`` and ``entries`` to a new file and swap it in at ``path`` atomically.

    Raises OSError (the temporary file is removed) when the disk will not take it.
    """
    temporary = path.with_name(path.name + ".tmp")
    try:
        with open_nofollow(temporary, "w") as out:
            for key, value in binds.items():
                out.write(json.dumps({"bind": key, "id": value}) + "\n")
            for entry in entries:
                out.write(json.dumps(entry) + "\n")
            out.flush()
            os.fsync(out.fileno())
        os.replace(temporary, path)
    except OSError:
        with contextlib.suppress(OSError):
            temporary.unlink(missing_ok=True)
        raise
    fsync_dir(path)


def open_spool(path: Path, check: Callable[[dict[str, Any]], bool] | None = None) -> SpoolContents:
    """:func:`read_spool`, with the unreadable lines kept aside and logged: what an owner
    calls at start. A ``.bad`` file that cannot be written is logged with the lines."""
    contents = read_spool(path, check)
    if contents.bad:
        try:
            where = keep_aside(path, contents.bad)
        except OSError as error:
            log.error(
                "%s: %d unreadable line(s) skipped; cannot keep them aside (%s): %r",
                path,
                len(contents.bad),
                error,
                [line[:200] for line in contents.bad],
            )
        else:
            contents.kept = where
            log.warning(
                "%s: %d unreadable line(s) skipped and kept in %s", path, len(contents.bad), where
            )
    return contents


class Quarantine:
    """Writes the database refused for good, one fsync'd JSON line each, kept for a person."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.count = 0
        """Writes quarantined by this process."""

    def add(self, entry: dict[str, Any]) -> None:
        new = not self.path.exists()
        with open_nofollow(self.path, "a") as out:
            out.write(json.dumps(entry) + "\n")
            out.flush()
            os.fsync(out.fileno())
        if new:
            fsync_dir(self.path)
        self.count += 1

    def entries(self) -> list[dict[str, Any]]:
        """Everything quarantined so far (also by earlier runs), oldest first."""
        if not self.path.exists():
            return []
        out = []
        with open_nofollow(self.path, "rb") as lines:
            for line in lines:
                try:
                    out.append(json.loads(line))
                except ValueError:  # a torn line, or bytes that are not UTF-8
                    continue
        return out
