"""A running activity: one behavior's state machine driven by the manager's commands."""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass, field
from datetime import datetime, timedelta
from enum import Enum
from typing import Any

from activities.engine import Event, Node, Runtime, Status, Wake
from activities.gaze import GazeKeeper

log = logging.getLogger(__name__)


class ActivityStatus(Enum):
    """Where a running activity stands, as its manager reports it."""

    RUNNING = "running"
    """Started and ticking; not finished."""
    PAUSED = "paused"
    """Frozen by ``pause``: nothing happens until ``resume``."""
    COMPLETED = "completed"
    """Reached one of its outcomes; ``result.outcome`` names it."""
    FAILED = "failed"
    """Could not go on (a robot command failed or timed out); ``result.error`` says why."""
    CANCELLED = "cancelled"
    """Stopped from outside: at once by ``cancel``, or by ``preempt`` once its cleanup ran."""


@dataclass(frozen=True)
class ActivityResult:
    """How an activity ended (or ``outcome=""`` while it runs)."""

    outcome: str = ""
    redirect: str | None = None
    """The activity to run next (the menu's choice): reason ``activity_redirect``."""
    error: str | None = None
    data: dict[str, Any] = field(default_factory=dict)
    """The root userdata at the end (scores, answers...)."""


class Activity:
    """One behavior instance: start, tick, pause, resume, cancel, deliver events.

    Its methods take the daemon's wall time ``now`` and turn it once into the steady
    time (``ctx.steady``): every wait, timer and limit inside, and the commands sent,
    run on it, so that a wall clock set back or forward neither cuts nor stretches them.
    """

    def __init__(
        self, name: str, root: Node, runtime: Runtime, gaze: GazeKeeper | None = None
    ) -> None:
        self.name = name
        self.root = root
        self.runtime = runtime
        self.gaze = gaze
        """The behavior's ``attend:``: keeps the gaze on the person while it runs."""
        self.userdata: dict[str, Any] = {}
        self.status: ActivityStatus | None = None
        self._result = ActivityResult()
        self.started_at: datetime | None = None
        """When it started, on the steady clock."""
        self.ticks = 0
        self._stop_by: datetime | None = None
        self._sleep: Wake | None = None
        """What the sleeping machine waits for: until it comes, a tick of the machine
        would do nothing and is skipped."""
        self._sleep_epoch = 0
        """``runtime.epoch`` when the machine fell asleep. Whatever reaches the machine
        from outside (a pause, a resume, a preemption, an event taken, a stop) moves the
        epoch, which wakes it."""
        self.skipped = 0
        """Ticks skipped while the machine slept (for the tests and benchmarks)."""
        self._path = ""
        self._path_epoch = -1

    @property
    def result(self) -> ActivityResult:
        return self._result

    @property
    def stopping(self) -> bool:
        """Preempted and running its cleanup states (``preempt``), not finished yet."""
        return self._stop_by is not None and not self.finished

    @property
    def finished(self) -> bool:
        return self.status in (
            ActivityStatus.COMPLETED,
            ActivityStatus.FAILED,
            ActivityStatus.CANCELLED,
        )

    def _steady(self, now: datetime) -> datetime:
        return self.runtime.ctx.steady(now)

    def start(self, now: datetime) -> ActivityStatus:
        """Enter the first state and run the first tick (commands go out at once)."""
        return self._start(self._steady(now))

    def _start(self, now: datetime) -> ActivityStatus:
        if self.status is not None:
            return self.status
        self.started_at = now
        self.status = ActivityStatus.RUNNING
        self.root.reset()
        self.root.bind(self.userdata)
        return self._tick(now)

    def tick(self, now: datetime) -> ActivityStatus:
        """Advance the machine once; never blocks."""
        return self._tick(self._steady(now))

    def _tick(self, now: datetime) -> ActivityStatus:
        if self.status is None:
            return self._start(now)
        if self.finished or self.status is ActivityStatus.PAUSED:
            return self.status
        if self._stop_by is not None and now >= self._stop_by:
            log.info("activity %s: cleanup still running at its limit, stopped", self.name)
            self._cancel(now)
            return self.status
        self.ticks += 1
        try:
            status = self._tick_root(now)
        except Exception as error:  # a broken block fails its activity, never the daemon
            self._contain(now, error)
            return self.status
        if self.gaze is not None and status is Status.RUNNING:
            self.gaze.update(now)
        if status is Status.DONE:
            ended = ActivityStatus.CANCELLED if self._stop_by else ActivityStatus.COMPLETED
            self._end(ended, self.root.outcome or "", None)
        elif status is Status.FAILED:
            self._end(ActivityStatus.FAILED, "failed", self.root.error or "failed")
        return self.status

    def _tick_root(self, now: datetime) -> Status:
        """Tick the machine, unless it sleeps; after a tick that left it running, ask
        what it waits for (the states entered in that tick have run once)."""
        if self._asleep(now):
            self.skipped += 1
            return Status.RUNNING
        status = self.root.tick(now)
        self._sleep = self.root.wake(now) if status is Status.RUNNING else None
        self._sleep_epoch = self.runtime.epoch
        return status

    def _asleep(self, now: datetime) -> bool:
        """Nothing reached the machine since it fell asleep, and what it waits for has
        not come by ``now``."""
        return (
            self._sleep is not None
            and self._sleep_epoch == self.runtime.epoch
            and self._sleep.holds(now)
        )

    def pause(self, now: datetime) -> None:
        """Freeze at any depth; commands in flight are withdrawn (history keeps the state)."""
        if self.status is ActivityStatus.RUNNING:
            now = self._steady(now)
            self.root.pause(now)
            if self.gaze is not None:
                self.gaze.withdraw(now)
            self.status = ActivityStatus.PAUSED

    def resume(self, now: datetime) -> None:
        """Re-enter the interrupted states; their blocks restart what they were doing."""
        self._resume(self._steady(now))

    def _resume(self, now: datetime) -> None:
        if self.status is ActivityStatus.PAUSED:
            self.status = ActivityStatus.RUNNING
            if self.gaze is not None:
                self.gaze.restart()
            self.root.resume(now)

    def preempt(self, now: datetime, limit_s: float) -> ActivityStatus:
        """Stop from outside the SMACH way: ask the active states to preempt, tick once.

        States that declare a ``preempted`` transition follow it, so cleanup states
        run (the quiz says it is stopping) in this tick and the next ones; the activity
        then ends ``CANCELLED`` with the root's outcome. A paused activity is resumed
        with the request already on its frozen states (the shoulder's "stop?" dialog
        paused it), so it goes straight to its cleanup; an unstarted one is cancelled
        at once, and cleanup still running ``limit_s`` after the request is cut off.
        """
        now = self._steady(now)
        if self.status is ActivityStatus.PAUSED:  # the request reaches the frozen leaves,
            self.root.preempt_active()  # which then do not restart what they said
            self._resume(now)
        if self.status is not ActivityStatus.RUNNING:
            self._cancel(now)
            return ActivityStatus.CANCELLED if self.status is None else self.status
        if self._stop_by is not None:  # asked already: one request
            return self.status
        self._stop_by = now + timedelta(seconds=limit_s)
        self.root.preempt()
        return self._tick(now)

    def cancel(self, now: datetime) -> None:
        """Stop from outside at once: every active state, at every depth, no cleanup."""
        self._cancel(self._steady(now))

    def _cancel(self, now: datetime) -> None:
        if self.status is None:
            self.status = ActivityStatus.CANCELLED
            self._result = ActivityResult("cancelled", None, None, {})
            return
        if self.finished:
            return
        self.root.stop(now)
        self._end(ActivityStatus.CANCELLED, "cancelled", None)

    def deliver(self, event: Event) -> bool:
        """Offer a perception event; True if a state took it (an answer, a guard)."""
        if self.status is not ActivityStatus.RUNNING:
            return False
        return self.root.deliver(event)

    @property
    def state_path(self) -> str:
        """The active states below the root, e.g. ``GAME/ROUNDS/ROUND/ASK``."""
        # Read at the end of every tick for ``dms/state``, but it changes only when a
        # state's status does, and every such change moves ``runtime.epoch``. Walking the
        # machine at every tick, with the tick's messages validated at every tick (see
        # TickRecord), cost 6 % of the 30-day simulation's instructions (14.5 G, not 13.7
        # G, for 3 days: bench/bench_instructions.py --days 3 --hash-seed 0).
        epoch = self.runtime.epoch
        if self._path_epoch != epoch:
            self._path, self._path_epoch = self.root.active_path(), epoch
        return self._path

    def structure(self) -> dict[str, Any]:
        """States, transitions, nesting and the active path: for a live viewer."""
        return {
            "name": self.name,
            "status": self.status.value if self.status is not None else "created",
            "active_path": self.state_path,
            "root": self.root.describe(),
        }

    def _contain(self, now: datetime, error: Exception) -> None:
        where = self.state_path or self.name
        try:
            self.root.stop(now)
        except Exception as second:  # stopping what broke may break again: report the first
            log.warning("activity %s: stop after an error raised %r", self.name, second)
        self._end(ActivityStatus.FAILED, "failed", f"{where}: {type(error).__name__}: {error}")

    def _end(self, status: ActivityStatus, outcome: str, error: str | None) -> None:
        self.status = status
        self._result = ActivityResult(
            outcome, self.runtime.redirect, error, _json_safe(self.userdata)
        )


def _json_safe(data: Mapping[str, Any]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in data.items():
        if isinstance(value, str | int | float | bool | type(None) | list | dict):
            out[key] = value
    return out
