"""The memory package's exceptions.

::

    DmsError
     └── ProfileError            a profile value, a database or a request is wrong
          ├── ProfileNotFound    no profile for this user id (also a KeyError)
          ├── StoreUnavailable   the database failed while running: retry later
          └── SchemaOutOfDate    the database needs ``dms db upgrade``
"""

from __future__ import annotations

from dms.errors import DmsError


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
