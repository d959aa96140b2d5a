"""Requests for an activity, on their way from the events to the choice.

An app, a caregiver, the user's voice or a touch on the screen asks to start or stop an
activity; :class:`~dms.controller.events.Events` puts the request here when it handles
the input, and :class:`~dms.controller.choice.Choice` takes it at this tick's decision
point (the cancel reasons, or the choice when nothing runs). The queue is the only way
between them: the events never decide, the choice never reads an input.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

from dms.kernel.messages import ChosenBy


@dataclass(frozen=True)
class Asked:
    """A start or cancel asked for, served at the next decision point of this tick."""

    target: str
    """The activity to start; empty for a cancel."""
    chosen_by: ChosenBy | None
    detail: str
    own: bool
    """The user's own act (voice, screen, a request ``by`` the user), not an app's or a
    caregiver's: only the user's own acts tell their proactivity and preferences."""


class Requests:
    """Starts and cancels asked for, in the order they came."""

    def __init__(self) -> None:
        self._queue: deque[Asked] = deque()

    def put(self, asked: Asked) -> None:
        self._queue.append(asked)

    def withdraw(self, activity: str | None) -> bool:
        """Drop a start of ``activity`` still waiting (a cancel came after it in the same
        tick: it never starts); True if there was one."""
        for asked in self._queue:
            if asked.target and asked.target == activity:
                self._queue.remove(asked)
                return True
        return False

    def take(self) -> Asked | None:
        """The oldest request, now served; None if none waits."""
        return self._queue.popleft() if self._queue else None
