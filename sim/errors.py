"""The sim package's exceptions.

``SimError`` (a :class:`dms.kernel.errors.DmsError`) is the root: the CLI prints it as one
``dms: ...`` line. ``SpecError`` names the file, line and field of a bad persona or
scenario; ``RecordingError`` a recording that cannot be read or written.
"""

from __future__ import annotations

from dms.kernel.errors import DmsError


class SimError(DmsError):
    """A simulation could not be set up or run."""


class SpecError(SimError, ValueError):
    """A persona or scenario file is wrong: the message names file, line and field."""


class RecordingError(SimError):
    """An MCAP recording cannot be written or read."""


class ExpectationFailed(SimError):
    """A scenario's expectation did not hold (``dms sim run`` exits 1 naming it)."""
