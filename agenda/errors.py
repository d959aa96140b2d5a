"""The agenda's exceptions.

::

    DmsError
     └── AgendaError            bad item, bad schedule, unknown user, schema out of date
          └── AgendaNotFound    (also a KeyError) no item with that id
"""

from __future__ import annotations

from dms.kernel.errors import DmsError


class AgendaError(DmsError):
    """A problem with the agenda, reported to a person in one line."""


class AgendaNotFound(AgendaError, KeyError):
    """No agenda item has that id."""

    def __str__(self) -> str:
        # KeyError would quote the message; it is meant to be read.
        return str(self.args[0]) if self.args else "no such agenda item"
