"""The memory package's exceptions.

::

    DmsError
     └── ProfileError            a profile value, a database or a request is wrong
          ├── ProfileNotFound    no profile for this user id (also a KeyError)
          ├── StoreUnavailable   the database failed for a while (lock, connection): retry later
          ├── StoreRefused       the database refused this one request (constraint, bad
          │                      data, missing table): retrying will not help
          ├── SchemaOutOfDate    the database needs ``dms db upgrade``
          └── StoreDamaged       tables are missing: ``dms db upgrade`` or a restore
"""

from __future__ import annotations

from dms.kernel.errors import DmsError


class ProfileError(DmsError):
    """A profile value, the database or a request is wrong; the message is one line."""


class ProfileNotFound(ProfileError, KeyError):
    """No profile is stored for this user id."""

    def __str__(self) -> str:
        # KeyError's __str__ quotes its argument; we want the plain one-line message.
        return str(self.args[0]) if self.args else "profile not found"


class StoreUnavailable(ProfileError):
    """The database failed while running (locked, gone, disconnected): try again later."""


class SchemaOutOfDate(ProfileError):
    """The database was made by an older schema; ``dms db upgrade`` brings it up to date."""


class StoreRefused(ProfileError):
    """The database refused this request for good (a constraint, a value it cannot store,
    a missing table or column); retrying it will not help, the writes behind it go on."""


class StoreDamaged(ProfileError):
    """The database is at the right revision but tables are missing (dropped by hand, a
    partial restore); ``dms db upgrade`` recreates them empty, or restore a backup."""


def one_line(error: BaseException) -> str:
    """A database error's first line, for a one-line message."""
    text = str(getattr(error, "orig", None) or error).strip().splitlines()
    return text[0] if text else type(error).__name__
