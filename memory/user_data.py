"""Other packages' rows about users, covered by the store's export and erase.

The agenda keeps a user's items and log in the same database; it registers a
:class:`UserData` part here when it is imported, so that :meth:`memory.ProfileStore.export`
and :meth:`memory.ProfileStore.erase` include them, in the same transaction, without the
memory package importing the agenda.
"""

from __future__ import annotations

from typing import Any, Protocol

from sqlalchemy.orm import Session


class UserData(Protocol):
    """Rows about users that another package keeps in the same database (the agenda).

    Registered with :func:`register_user_data` so that :meth:`ProfileStore.export` and
    :meth:`ProfileStore.erase` cover them too, in the same transaction, without the
    memory package importing the other one.
    """

    name: str
    """The key of this part in the export."""

    def export_user(self, session: Session, user_id: str) -> Any | None:
        """Everything this part stores about ``user_id``, JSON-able; None if it has no tables."""
        ...

    def erase_user(self, session: Session, user_id: str) -> None:
        """Delete every row this part stores about ``user_id``."""
        ...


_PARTS: dict[str, UserData] = {}


def register_user_data(part: UserData) -> None:
    """Add ``part`` to every export and erase (called when its package is imported)."""
    _PARTS[part.name] = part


def parts() -> list[UserData]:
    """The registered parts, in the order they were registered."""
    return list(_PARTS.values())
