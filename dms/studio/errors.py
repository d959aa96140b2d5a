"""The error every part of the studio raises for a request it refuses.

Apart from the folder so that the daemon's side of the studio (trying a behavior on
the running robot) loads without the round-trip YAML library the folder writes with.
"""

from __future__ import annotations

from dms.kernel.errors import DmsError


class StudioError(DmsError):
    """A request the studio refuses, with the HTTP status that says why."""

    def __init__(self, message: str, status: int = 400) -> None:
        super().__init__(message)
        self.status = status
