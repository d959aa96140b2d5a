"""The daemon's controller stack on a virtual clock, with scripted and simulated users.

:class:`Simulation` builds the same stack as ``dms run`` (:func:`dms.assembly.build_stack`)
over the in-process :class:`sim.robot.SimRobot`, a fresh SQLite file and a
:class:`~dms.kernel.clock.VirtualClock`, and runs it the way the daemon does: a tick every
``tick_period_s`` (2 Hz) and one at once when an urgent input (touch, speech, screen,
request) arrives. Inputs enter through :meth:`InputBoard.accept`, exactly as the bus
would deliver them; the user in front of the robot hears every robot command and sees
every decision.

Between inputs nothing happens but the clock, so the simulation runs as fast as the
controller ticks. :attr:`Simulation.idle_step_s` lets a long run take larger virtual
steps while nobody is present and no dialog is open (the motivation model steps
exactly for any ``dt``), but never past the 2 Hz tick at which the motivated behavior
changes; see docs/simulation.md for what ``ticks`` counts.
"""

from __future__ import annotations

import heapq
import itertools
import math
import random
import tempfile
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import datetime, timedelta
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pydantic import BaseModel

from dms.config import Settings
from dms.kernel import keys
from dms.kernel.clock import VirtualClock
from dms.kernel.messages import Decision, RobotCommand, UserPerception
from sim.user import SimulatedUser

if TYPE_CHECKING:
    from dms.assembly import Stack
    from dms.controller import TickRecord

ScriptedAction = Callable[[], None]


@dataclass(frozen=True, slots=True)
class TimedDecision:
    """A decision and the virtual second it was taken at (from the start)."""

    t: float
    decision: Decision


@dataclass(order=True)
class _Scheduled:
    t: float
    order: int
    action: ScriptedAction = field(compare=False)
    urgent: bool = field(compare=False, default=False)


def _no_fsync(engine: Any) -> None:
    """``synchronous=OFF`` on a throw-away database the simulation made itself.

    A shortcut for the simulations' wall time: with an fsync per profile write and
    agenda claim, a 10-day run took about 1.5 times as long (measured). What is read
    back is the same; only durability across a power cut is lost, and the file is
    deleted."""
    from sqlalchemy import event

    def pragma(dbapi_connection: Any, _record: Any) -> None:
        cursor = dbapi_connection.cursor()
        cursor.execute("PRAGMA synchronous=OFF")
        cursor.close()

    event.listen(engine, "connect", pragma)  # after memory.db's own pragmas
    engine.dispose()  # connections already pooled reopen with it


class Simulation:
    """One robot's controller stack on a virtual clock."""

    def __init__(
        self,
        settings: Settings | None = None,
        *,
        seed: int = 0,
        start: datetime | None = None,
        workdir: Path | None = None,
        with_memory: bool = True,
        launch_delay_s: tuple[float, float] = (0.0, 0.0),
    ) -> None:
        from dms.assembly import AGENDA_POLL_S, build_stack
        from sim.robot import SimRobot

        settings = settings or Settings()
        self._tmp: tempfile.TemporaryDirectory[str] | None = None
        if settings.db is None and with_memory:
            if workdir is None:
                self._tmp = tempfile.TemporaryDirectory(prefix="dms-sim-")
                workdir = Path(self._tmp.name)
            settings = settings.model_copy(update={"db": f"sqlite:///{workdir / 'sim.db'}"})
        self.settings = settings.model_copy(update={"seed": seed})
        self.clock = VirtualClock(start)
        self.start = self.clock.now()
        self.robot = SimRobot(rng_seed=seed, launch_delay_s=launch_delay_s)
        self.robot.process_of = self._process_of
        self.errors: list[tuple[float, str, str]] = []
        self.decisions: list[TimedDecision] = []
        self.commands = 0
        self.user: SimulatedUser | None = None
        """The simulated user in front of the robot, if any."""
        self.presence: UserPerception | None = None
        """A scripted perception/user refreshed every tick (when no simulated user)."""
        self.perception_on = True
        self.period = self.settings.controller.tick_period_s
        self.idle_step_s: float | None = None
        self.periodic = True
        """False: tick only when told (a replay ticks at the recorded times)."""
        self.ticks = 0
        self.last: TickRecord | None = None
        self.decision_listeners: list[Callable[[TimedDecision], None]] = []
        self.tick_listeners: list[Callable[[TickRecord], None]] = []
        self.command_listeners: list[Callable[[RobotCommand, datetime], None]] = []
        self._queue: list[_Scheduled] = []
        self._order = itertools.count()
        self._next_tick = 0.0
        try:
            self.stack: Stack = build_stack(
                self.settings,
                self.robot,
                on_command=self._on_command,
                report_error=self._on_error,
                rng=random.Random(seed),
                with_memory=with_memory,
                retrain=False,
                background_io=False,
                # a database the simulation made itself: nobody else adds items to it, so
                # no poll; the decisions are the same either way. A shortcut for the wall
                # time: a poll every 10 s of the virtual clock made a 10-day run take about
                # 1.5 times as long (9.3-11.5 s of CPU against 6.9-7.1 s, measured)
                agenda_poll_s=None if self._tmp is not None else AGENDA_POLL_S,
            )
        except BaseException:
            self._cleanup_tmp()
            raise
        if self._tmp is not None:
            for part in (self.stack.store, self.stack.agenda):
                if part is not None:
                    _no_fsync(part.engine)
        self.controller = self.stack.controller

    # ------------------------------------------------------------ plumbing

    def close(self) -> None:
        """Close the store and remove the temporary database."""
        self.stack.close()
        self._cleanup_tmp()

    def _cleanup_tmp(self) -> None:
        if self._tmp is not None:
            self._tmp.cleanup()
            self._tmp = None

    def __enter__(self) -> Simulation:
        return self

    def __exit__(self, *_exc: object) -> None:
        self.close()

    @property
    def t(self) -> float:
        """Virtual seconds since the start."""
        return self.clock.monotonic()

    def now(self) -> datetime:
        return self.clock.now()

    def _on_command(self, command: RobotCommand) -> None:
        self.commands += 1
        now = self.clock.now()
        if self.user is not None:
            self.user.on_command(command, now)
        for listener in self.command_listeners:
            listener(command, now)

    def _process_of(self, command: RobotCommand) -> tuple[str, datetime] | None:
        """The activity run that sends ``command`` (its name and start), for the robot's
        launch delay: the arbiter's active handle on the channel names the source, the
        controller's current or paused activity of that name is the run."""
        handle = self.stack.expression.active(command.channel)
        if handle is None or handle.command_id != command.id:
            return None
        if not handle.source.startswith("activity:"):
            return None
        name = handle.source[len("activity:") :]
        for running in (self.controller.current, self.controller.suspended):
            if running is not None and running.name == name:
                return name, running.started
        for manager in self.controller.managers.values():  # cancelled, cleaning up
            for activity in manager.winding_down:
                if activity.name == name and activity.started_at is not None:
                    return name, activity.started_at
        # Being started in this very tick (the manager's start sends its first command
        # before the controller records the run): the run will start now.
        return name, self.clock.now()

    def _on_error(self, key: str, error: str) -> None:
        self.errors.append((self.t, key, error))

    def feed(self, key: str, message: BaseModel) -> None:
        """Deliver one input now, as the bus would."""
        self.stack.inputs.accept(key, message, self.clock.monotonic())

    # ------------------------------------------------------------ users

    def seat(self, user: SimulatedUser) -> None:
        """``user`` comes to the robot (and is in front of it until :meth:`unseat`)."""
        self.user = user
        self.presence = None
        user.arrive(self.clock.now())
        self.feed(keys.PERCEPTION_USER, user.perception(self.clock.now()))

    def unseat(self) -> None:
        """The simulated user leaves."""
        if self.user is not None:
            self.user.leave(self.clock.now())
            self.user = None
        self.presence = UserPerception(present=False, user_id=None, ready=False, engagement=None)
        self.feed(keys.PERCEPTION_USER, self.presence)

    # ------------------------------------------------------------ the loop

    def at(self, t: float, action: ScriptedAction, urgent: bool = False) -> None:
        """Run ``action`` at virtual second ``t``; an urgent one is followed by a tick."""
        heapq.heappush(self._queue, _Scheduled(t, next(self._order), action, urgent))

    def tick(self, urgent: bool = False) -> TickRecord:
        """One controller tick now, with the perception refreshed first."""
        clock = self.clock  # the clock stands still during a tick
        now, t = clock.now(), clock.monotonic()
        if self.perception_on:  # a refresh of what is perceived, not a new input
            if self.user is not None:
                perceived = self.user.perception(now)
                self.stack.inputs.accept(keys.PERCEPTION_USER, perceived, t)
            elif self.presence is not None:
                self.stack.inputs.accept(keys.PERCEPTION_USER, self.presence, t)
        record = self.controller.tick(now, t, urgent)
        self.ticks += 1
        self.last = record
        for decision in record.decisions:
            timed = TimedDecision(t, decision)
            self.decisions.append(timed)
            if self.user is not None:
                self.user.on_decision(decision, now)
            for listener in self.decision_listeners:
                listener(timed)
        for tick_listener in self.tick_listeners:
            tick_listener(record)
        return record

    def _user_outputs(self) -> bool:
        """Deliver what the user in front does by now; True if any of it is urgent."""
        user = self.user
        if user is None:
            return False
        now = self.clock.now()
        urgent = False
        for key, message in user.due(now):
            self.feed(key, message)
            urgent = urgent or key in keys.URGENT_INPUTS
        return urgent

    def _user_due_t(self) -> float | None:
        if self.user is None:
            return None
        due = self.user.next_due()
        return None if due is None else (due - self.start).total_seconds()

    def _step(self) -> float:
        """The period to the next periodic tick: larger while idle, if allowed."""
        idle = self.idle_step_s
        if idle is None or self.user is not None:
            return self.period
        if self.presence is not None and self.presence.present:
            return self.period
        if self.controller.dialog is not None:
            return self.period
        # Never past the tick where the motivated behavior changes: the switch stays exact.
        change = self.controller.next_motivated_change(self.clock.now(), idle)
        return idle if change is None else max(self.period, change)

    def run_until(self, t_end: float) -> None:
        """Tick (periodically and on urgent inputs) until virtual second ``t_end``."""
        queue = self._queue
        while True:
            upcoming = self._next_tick if self.periodic else math.inf
            if queue and queue[0].t < upcoming:
                upcoming = queue[0].t
            user_t = self._user_due_t()
            if user_t is not None and user_t < upcoming:
                upcoming = user_t
            if upcoming > t_end:
                break
            if upcoming > self.t:
                self.clock.advance(upcoming - self.t)
            urgent = False
            while queue and queue[0].t <= self.t:
                scheduled = heapq.heappop(queue)
                scheduled.action()
                urgent = urgent or scheduled.urgent
            urgent = self._user_outputs() or urgent
            periodic = self.periodic and self._next_tick <= self.t
            if periodic or urgent:
                self.tick(urgent=urgent and not periodic)
            if periodic:
                step = self._step()  # once: an idle step simulates the motivation ahead
                t = self.t
                self._next_tick = t + step
                # Never step over something scheduled: an arrival, a scripted input.
                if queue and queue[0].t < self._next_tick and step > self.period:
                    self._next_tick = max(t + self.period, queue[0].t)
        if t_end > self.t:
            self.clock.advance(t_end - self.t)

    def run_for(self, seconds: float) -> None:
        self.run_until(self.t + seconds)

    def when(self, t: float) -> datetime:
        return self.start + timedelta(seconds=t)
