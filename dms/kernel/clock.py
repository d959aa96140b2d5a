"""Clocks: the one place that reads time.

The daemon's entry point builds a :class:`RealClock`; tests and simulation build a
:class:`VirtualClock` and advance it. Everything below the entry point receives
``now`` (a timezone-aware UTC ``datetime``) from the clock instead of reading the
system time, so the same code runs live and on a virtual timeline.

Two clocks, two jobs. The monotonic clock measures: the drives' steps, timeouts, rate
limits, and through :class:`SteadyTime` the durations kept as datetimes (a dialog's
deadline, an activity's wait, the simulated robot's commands). The wall clock names:
schedules, log lines, the hour of the daily rhythm. An administrator or NTP may set the
wall clock back or forward at any moment; :class:`WallSteps` notices it, so that it can
be reported, and nothing that measures time moves with it.
"""

from __future__ import annotations

import contextlib
import queue
import time
from collections.abc import Iterator
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from typing import Protocol

TICK_PERIOD_S = 0.5
"""The decision loop's period: 2 Hz, as in the paper."""

WALL_STEP_S = 2.0
"""How far the wall clock may drift from the monotonic one between two readings before
it counts as set (NTP slews by far less; a tick late by load moves both clocks alike)."""


class Clock(Protocol):
    """What the daemon needs to know about time."""

    def now(self) -> datetime:
        """The current wall time, timezone-aware UTC."""
        ...

    def monotonic(self) -> float:
        """Seconds on a clock that never goes back; for deadlines and durations."""
        ...


class RealClock:
    """The system clock. Only the daemon's entry point should create one."""

    def now(self) -> datetime:
        return datetime.now(UTC)

    def monotonic(self) -> float:
        return time.monotonic()


class VirtualClock:
    """A clock that moves only when told to; for tests and simulation."""

    def __init__(self, start: datetime | None = None) -> None:
        start = start or datetime(2026, 11, 23, 9, 0, tzinfo=UTC)
        if start.tzinfo is None:
            raise ValueError("VirtualClock needs a timezone-aware start time")
        self._start = start.astimezone(UTC)
        """The wall time at monotonic 0 (moved by :meth:`step_wall`)."""
        self._elapsed = 0.0
        self._now = self._start
        self._now_at = 0.0

    def now(self) -> datetime:
        # Read a few times a tick by the simulation: made once per clock position.
        if self._now_at != self._elapsed:
            self._now = self._start + timedelta(seconds=self._elapsed)
            self._now_at = self._elapsed
        return self._now

    def monotonic(self) -> float:
        return self._elapsed

    def advance(self, seconds: float) -> datetime:
        """Move time forward by ``seconds`` (never back) and return the new now."""
        if seconds < 0:
            raise ValueError("a virtual clock never goes back")
        self._elapsed += seconds
        return self.now()

    def set(self, when: datetime) -> None:
        """Jump forward to ``when``."""
        delta = (when - self._start).total_seconds()
        if delta < self._elapsed:
            raise ValueError("a virtual clock never goes back")
        self._elapsed = delta

    def step_wall(self, seconds: float) -> None:
        """Set the wall clock ``seconds`` forward (negative: back), as an administrator
        or NTP would; the monotonic clock does not move."""
        self._start += timedelta(seconds=seconds)
        self._now_at = -1.0  # the wall time read last is stale


class WallSteps:
    """Notices the wall clock being set between two readings of both clocks.

    Over a step the wall clock moves by more (or less) than the monotonic clock;
    a difference over ``threshold_s`` is a step. Each step is seen once: the next
    readings compare with the stepped time.
    """

    def __init__(self, threshold_s: float = WALL_STEP_S) -> None:
        self.threshold_s = threshold_s
        self._last: tuple[datetime, float] | None = None

    def observe(self, now: datetime, monotonic: float) -> float | None:
        """The step in seconds (negative: back) since the last reading, or None."""
        last, self._last = self._last, (now, monotonic)
        if last is None:
            return None
        step = (now - last[0]).total_seconds() - (monotonic - last[1])
        return step if abs(step) > self.threshold_s else None


class SteadyTime:
    """The wall time with the wall clock's steps taken out: the time durations are
    measured on (dialog deadlines, grace periods, an activity's waits, the robot's
    commands), while schedules, logs and names keep the wall time.

    It moves with the monotonic clock, and is the wall time itself until the wall clock
    is first set (:class:`WallSteps`): a simulation, whose clocks move together, sees
    the very same times. Each step then stays as an offset, so a question open when an
    administrator sets the clock forward an hour still has its whole time to be answered.
    """

    def __init__(self, threshold_s: float = WALL_STEP_S) -> None:
        self._steps = WallSteps(threshold_s)
        self.offset = timedelta(0)
        """The wall time less the steady time: the sum of the steps seen."""

    def observe(self, now: datetime, monotonic: float) -> None:
        """Called once a tick with both clocks: takes a step of the wall clock out."""
        step = self._steps.observe(now, monotonic)
        if step is not None:
            self.offset += timedelta(seconds=step)

    def steady(self, now: datetime) -> datetime:
        """``now`` (the wall time of the last :meth:`observe`) on the steady clock."""
        return now - self.offset


def describe_step(seconds: float) -> str:
    """``"back 1 h 0 min 5 s"``: a wall-clock step for a person to read."""
    whole = round(abs(seconds))
    hours, rest = divmod(whole, 3600)
    minutes, secs = divmod(rest, 60)
    if hours:
        size = f"{hours} h {minutes} min {secs} s"
    elif minutes:
        size = f"{minutes} min {secs} s"
    else:
        size = f"{abs(seconds):.1f} s"
    return f"{'back' if seconds < 0 else 'forward'} {size}"


@dataclass(frozen=True, slots=True)
class TickTiming:
    """When a tick was due and when it actually started (monotonic seconds)."""

    index: int
    due: float
    started: float


class Ticker:
    """Yields ticks at a fixed period against monotonic deadlines, so it never drifts.

    The next deadline is always ``previous deadline + period``; the time spent doing
    the work is not added on top. A tick that falls more than one period behind is
    skipped rather than bunched, and counted in :attr:`missed`.

    :meth:`wake` lets another thread (an urgent input) end the current wait early;
    the woken iteration yields the same deadline again with ``urgent=True``.

    :meth:`wake` and :meth:`stop` take no lock of Python's: the daemon's signal handlers
    call :meth:`stop` in the main thread, which may be inside the loop's own wait at that
    moment, and a ``threading.Event`` there deadlocks when the handler comes while the
    waiting thread holds the Event's lock. They put a word on a ``SimpleQueue``, whose
    ``put`` is reentrant.
    """

    def __init__(self, clock: Clock, period: float = TICK_PERIOD_S) -> None:
        self._clock = clock
        self._period = period
        self._calls: queue.SimpleQueue[bool] = queue.SimpleQueue()
        """What came during a wait: True for a stop, False for a wake."""
        self._stopped = False
        self.missed = 0

    def wake(self) -> None:
        """Ask the loop to run now (an urgent input arrived)."""
        self._calls.put(False)

    def stop(self) -> None:
        """End the loop before its next tick; safe in a signal handler."""
        self._stopped = True
        self._calls.put(True)

    @property
    def stopped(self) -> bool:
        return self._stopped

    def _woken(self, timeout: float) -> bool:
        """Wait up to ``timeout`` for a wake or a stop; the wakes that came meanwhile
        make one urgent tick."""
        try:
            self._calls.get(timeout=timeout)
        except queue.Empty:
            return False
        with contextlib.suppress(queue.Empty):
            while True:
                self._calls.get_nowait()
        return True

    def __iter__(self) -> Iterator[tuple[TickTiming | None, bool]]:
        """Yield ``(timing, urgent)``: timing for a periodic tick, None for an urgent wake."""
        deadline = self._clock.monotonic()
        index = 0
        while not self._stopped:
            remaining = deadline - self._clock.monotonic()
            if remaining > 0:
                woke = self._woken(remaining)
                if self._stopped:
                    return
                if woke:
                    yield None, True
                    continue
            started = self._clock.monotonic()
            behind = int((started - deadline) // self._period)
            if behind >= 1:
                self.missed += behind
                deadline += behind * self._period
            yield TickTiming(index, deadline, started), False
            index += 1
            deadline += self._period


def iso(t: datetime) -> str:
    """ISO-8601 UTC with milliseconds and a trailing Z, as docs/contract.md asks."""
    t = t.astimezone(UTC)
    return t.strftime("%Y-%m-%dT%H:%M:%S.") + f"{t.microsecond // 1000:03d}Z"
