"""The tick's fault barrier: an exception in one step is reported, never fatal.

The controller runs each step of a tick (an event, the motivation, the robot's
feedback, the user's presence, the dialog, the activity, the cancel reasons, the
choice) through :meth:`FaultBarrier.run`. An exception that escapes a step is logged
with its traceback, reported on ``dms/errors`` as ``tick/<step>`` with the input it was
working on, and swallowed: ``run`` returns False, the step's caller puts its own
state back in order (drops the event, fails the activity, closes the dialog) and the
loop goes on.

A step that fails every tick would flood ``dms/errors`` at 2 Hz: the same fault (same
step, same exception type and message) is reported at once, then at most every
:data:`REPEAT_EVERY_S` with how many times it came back meanwhile.

APScheduler's ``_dispatch_event`` contains a failing listener the same way.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass
from typing import ParamSpec

from dms.kernel.ids import printable

log = logging.getLogger(__name__)

REPEAT_EVERY_S = 60.0

P = ParamSpec("P")


@dataclass(slots=True)
class _Seen:
    last_reported: float
    repeats: int = 0


@dataclass(frozen=True, slots=True)
class Fault:
    """One contained exception, for tests and counters."""

    step: str
    subject: str
    error: str


class FaultBarrier:
    """Contains exceptions per step; see the module docstring."""

    def __init__(
        self, report: Callable[[str, str], None], clock: Callable[[], float] | None = None
    ) -> None:
        """``report(key, line)`` publishes on ``dms/errors``; ``clock`` gives seconds
        (the controller passes its tick time, so a virtual clock deduplicates too)."""
        self._report = report
        self._clock = clock or (lambda: 0.0)
        self._seen: dict[tuple[str, str], _Seen] = {}
        self.faults: list[Fault] = []
        """Every contained fault (bounded: the latest 100)."""

    def run(
        self,
        name: str,
        subject: object,
        step: Callable[P, object],
        *args: P.args,
        **kwargs: P.kwargs,
    ) -> bool:
        """Run ``step(*args, **kwargs)`` as step ``name`` working on ``subject``.

        Returns False if it raised (the fault is contained), so that the caller can put
        its state back in order. KeyboardInterrupt and SystemExit are not ours to contain.
        """
        try:
            step(*args, **kwargs)
        except Exception as error:
            self.contain(name, subject, error)
            return False
        return True

    def contain(self, name: str, subject: object, error: Exception) -> None:
        """Log and report ``error``, raised by step ``name`` working on ``subject``."""
        what = printable(f"{type(error).__name__}: {error}", 300)
        about = printable(repr(subject), 300) if subject is not None else ""
        log.error("tick step %s failed%s", name, f" on {about}" if about else "", exc_info=error)
        self.faults.append(Fault(name, about, what))
        del self.faults[:-100]
        now = self._clock()
        seen = self._seen.get((name, what))
        if seen is not None and now - seen.last_reported < REPEAT_EVERY_S:
            seen.repeats += 1
            return
        repeats = f" (again {seen.repeats} times since)" if seen and seen.repeats else ""
        self._seen[(name, what)] = _Seen(now)
        if len(self._seen) > 1000:  # a fault whose message changes every time
            self._seen.clear()
        on = f" on {about}" if about else ""
        self._report(f"tick/{name}", f"{what}{on}; the loop goes on{repeats}")
