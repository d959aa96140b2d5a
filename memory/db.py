"""Engines for the daemon's database, shared by ``memory`` and ``agenda``.

Any SQLAlchemy URL works. For SQLite files the connection is made durable and
safe for one writer with concurrent readers: WAL journal, ``synchronous=FULL``
(an acknowledged commit survives a power cut or SIGKILL), a busy timeout and
foreign keys on.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from platformdirs import user_data_dir
from sqlalchemy import Engine, create_engine, event
from sqlalchemy.engine import make_url

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


def make_engine(url: str, **kwargs: Any) -> Engine:
    """An engine for ``url``; SQLite files get WAL, FULL sync, busy timeout, foreign keys."""
    url = as_url(url)
    parsed = make_url(url)
    if parsed.get_backend_name() == "sqlite":
        database = parsed.database
        if database and database != ":memory:":
            Path(database).expanduser().parent.mkdir(parents=True, exist_ok=True)
        engine = create_engine(
            url, connect_args={"timeout": SQLITE_BUSY_TIMEOUT_MS / 1000}, **kwargs
        )
        event.listen(engine, "connect", _sqlite_pragmas)
        return engine
    return create_engine(url, pool_pre_ping=True, **kwargs)


def _sqlite_pragmas(dbapi_connection: Any, _record: Any) -> None:
    cursor = dbapi_connection.cursor()
    cursor.execute("PRAGMA journal_mode=WAL")
    cursor.execute("PRAGMA synchronous=FULL")
    cursor.execute(f"PRAGMA busy_timeout={SQLITE_BUSY_TIMEOUT_MS}")
    cursor.execute("PRAGMA foreign_keys=ON")
    cursor.close()
