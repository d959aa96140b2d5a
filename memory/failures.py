"""How a database failure reaches the store's caller: passing, or a refusal for good.

:func:`classify` sorts a SQLAlchemy error into :class:`memory.errors.StoreUnavailable`
(retry later) or :class:`memory.errors.StoreRefused` (retrying will not help);
:func:`classified` applies it to a block of database work, with the two write races the
store resolves itself (:class:`Stale`, :class:`Conflict`).
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

from sqlalchemy.exc import (
    DatabaseError,
    DBAPIError,
    DisconnectionError,
    IntegrityError,
    InterfaceError,
    InternalError,
    OperationalError,
    SQLAlchemyError,
)
from sqlalchemy.exc import TimeoutError as PoolTimeout
from sqlalchemy.orm.exc import StaleDataError

from memory.errors import ProfileError, StoreRefused, StoreUnavailable, one_line

_TRANSIENT_SQLSTATE_CLASSES = ("08", "40", "53", "57", "58", "HY", "XX")
"""PostgreSQL error classes that pass: connection, rollback (serialization, deadlock),
resources, operator intervention (shutdown, statement timeout), system, internal."""
_TRANSIENT_SQLSTATES = frozenset({"55P03", "55006"})  # lock not available, object in use
_PERMANENT_SQLITE = ("no such table", "no such column", "has no column", "constraint failed")


def classify(error: SQLAlchemyError) -> StoreUnavailable | StoreRefused:
    """A database error as a passing trouble (retry later) or a refusal of this request.

    When in doubt it is passing: a write kept for a retry is never lost, one refused is
    set aside for good.
    """
    line = f"database error: {one_line(error)}"
    if not isinstance(error, DBAPIError):
        if isinstance(error, PoolTimeout | DisconnectionError):
            return StoreUnavailable(line)
        return StoreRefused(line)  # bad data caught before the database (a bind, a type)
    if error.connection_invalidated or isinstance(error, InterfaceError):
        return StoreUnavailable(line)
    sqlstate = getattr(error.orig, "sqlstate", None)
    if isinstance(sqlstate, str) and len(sqlstate) == 5:
        transient = sqlstate in _TRANSIENT_SQLSTATES or sqlstate.startswith(
            _TRANSIENT_SQLSTATE_CLASSES
        )
        return StoreUnavailable(line) if transient else StoreRefused(line)
    if isinstance(error, OperationalError):
        text = str(error.orig).lower()
        if any(part in text for part in _PERMANENT_SQLITE):
            return StoreRefused(line)
        return StoreUnavailable(line)  # locked, busy, disk I/O, cannot open, disk full
    if type(error) in (DBAPIError, DatabaseError) or isinstance(error, InternalError):
        return StoreUnavailable(line)  # no finer class (a damaged file, a driver fault)
    return StoreRefused(line)  # integrity, data, programming, not supported


class Conflict(StoreRefused):
    """A write collided with a row another writer made (a unique key)."""


class Stale(StoreUnavailable):
    """Another writer changed the row since this write read it (its version moved)."""


@contextmanager
def classified() -> Iterator[None]:
    """Database failures inside become StoreUnavailable or StoreRefused (:func:`classify`),
    a row changed under an ORM write :class:`Stale`, a key collision :class:`Conflict`;
    the store's own errors pass as they are."""
    try:
        yield
    except ProfileError:
        raise
    except StaleDataError as error:
        raise Stale(f"changed by another writer: {one_line(error)}") from None
    except IntegrityError as error:
        raise Conflict(f"refused by the database: {one_line(error)}") from None
    except SQLAlchemyError as error:
        raise classify(error) from None
