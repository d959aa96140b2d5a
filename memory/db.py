"""Engines for the daemon's database, shared by ``memory`` and ``agenda``.

Any SQLAlchemy URL works. For SQLite files the connection is made durable and
safe for one writer with concurrent readers: WAL journal, ``synchronous=FULL``
(an acknowledged commit survives a power cut or SIGKILL), a busy timeout and
foreign keys on.
"""

from __future__ import annotations

import contextlib
import hashlib
from pathlib import Path
from typing import Any

from platformdirs import user_data_dir, user_state_dir
from sqlalchemy import Engine, create_engine, event
from sqlalchemy.engine import make_url

from dms.kernel.files import LinkRefused, refuse_link
from memory.errors import ProfileError

SQLITE_BUSY_TIMEOUT_MS = 5000


def default_url() -> str:
    """The default store: ``dms.db`` in the user's data folder."""
    folder = Path(user_data_dir("dms", appauthor=False))
    folder.mkdir(parents=True, exist_ok=True)
    return f"sqlite:///{folder / 'dms.db'}"


def as_url(value: str) -> str:
    """A database URL from ``--db``: a URL as is, a plain file path as a SQLite file."""
    looks_like_file = (
        "/" in value or value.startswith("~") or value.endswith((".db", ".sqlite", ".sqlite3"))
    )
    if "://" in value or not looks_like_file:
        return value
    return f"sqlite:///{Path(value).expanduser().absolute()}"


def shown_url(url: str) -> str:
    """``url`` as messages show it: without its password (ArgumentError if it is no URL)."""
    return make_url(url).render_as_string(hide_password=True)


def side_file(url: str, suffix: str, owner: str | None = None) -> Path:
    """A local file that belongs to the database at ``url`` (the write spool, quarantine).

    Beside a SQLite file (``dms.db.spool``); for a server database, in the user's state
    folder, named after the URL without its password, so each database has its own.
    ``owner`` (a robot id) makes it that robot's own (``dms.db.hall.spool``): robots that
    share a database on one machine must not share a spool. A file of the same kind
    left under the name without an owner (an older version's) is taken over by the
    first owner that asks for it, so nothing it holds is lost.
    """
    parsed = make_url(as_url(url))
    database = parsed.database
    if parsed.get_backend_name() == "sqlite" and database and database != ":memory:":
        base = f"{Path(database).expanduser().absolute()}"
    else:
        shown = parsed.render_as_string(hide_password=True)
        digest = hashlib.sha256(shown.encode()).hexdigest()[:16]
        folder = Path(user_state_dir("dms", appauthor=False))
        folder.mkdir(parents=True, exist_ok=True)
        base = str(folder / f"db-{digest}")
    shared = Path(f"{base}.{suffix}")
    if owner is None:
        return shared
    own = Path(f"{base}.{owner}.{suffix}")
    if shared.exists() and not own.exists():
        with contextlib.suppress(OSError):  # another owner took it over first
            shared.rename(own)
    return own


def make_engine(url: str, busy_timeout_s: float | None = None, **kwargs: Any) -> Engine:
    """An engine for ``url``; SQLite files get WAL, FULL sync, busy timeout, foreign keys.

    ``busy_timeout_s`` (SQLite) is how long a statement waits for another process's lock
    before failing; the daemon's writer keeps it short and spools instead of waiting.
    """
    url = as_url(url)
    parsed = make_url(url)
    if parsed.get_backend_name() == "sqlite":
        database = parsed.database
        if database and database != ":memory:":
            refuse_links(Path(database).expanduser())
            Path(database).expanduser().parent.mkdir(parents=True, exist_ok=True)
        timeout_ms = round(
            SQLITE_BUSY_TIMEOUT_MS if busy_timeout_s is None else busy_timeout_s * 1000
        )
        engine = create_engine(url, connect_args={"timeout": timeout_ms / 1000}, **kwargs)

        def pragmas(dbapi_connection: Any, _record: Any) -> None:
            _sqlite_pragmas(dbapi_connection, timeout_ms)

        event.listen(engine, "connect", pragmas)
        return engine
    return create_engine(url, pool_pre_ping=True, **kwargs)


def refuse_links(database: Path) -> None:
    """ProfileError when the SQLite file or one of its own files (``-wal``, ``-shm``,
    ``-journal``) is a symbolic link: SQLite would write through it."""
    for path in (database, *(Path(f"{database}{end}") for end in ("-wal", "-shm", "-journal"))):
        try:
            refuse_link(path)
        except LinkRefused as error:
            raise ProfileError(str(error)) from None


def dialect_module(dialect: str) -> Any:
    """SQLAlchemy's module of ``dialect`` (``sqlite`` or ``postgresql``), for its upserts.

    Imported on use: a daemon on SQLite never loads PostgreSQL's (40-110 ms of its start).
    """
    if dialect == "sqlite":
        from sqlalchemy.dialects import sqlite

        return sqlite
    from sqlalchemy.dialects import postgresql

    return postgresql


def _sqlite_pragmas(dbapi_connection: Any, timeout_ms: int) -> None:
    cursor = dbapi_connection.cursor()
    cursor.execute("PRAGMA journal_mode=WAL")
    cursor.execute("PRAGMA synchronous=FULL")
    cursor.execute(f"PRAGMA busy_timeout={timeout_ms}")
    cursor.execute("PRAGMA foreign_keys=ON")
    cursor.close()
