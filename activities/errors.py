"""The activities package's exceptions.

::

    DmsError
     └── BehaviorError          a behavior file or call is wrong (file:line: state: message)
          └── UnknownBehavior   (also a KeyError) no behavior of that name
"""

from __future__ import annotations

from dms.kernel.errors import DmsError


class BehaviorError(DmsError):
    """A behavior file is wrong, or a behavior cannot be created; one line to show a person."""

    def __init__(self, message: str, problems: list[str] | None = None) -> None:
        super().__init__(message)
        self.problems: list[str] = problems if problems is not None else [message]


class UnknownBehavior(BehaviorError, KeyError):
    """``create`` was asked for a behavior the library does not have."""

    def __str__(self) -> str:
        return str(self.args[0])
