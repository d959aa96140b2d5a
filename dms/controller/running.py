"""The activity that runs, its managers, and the robot link that lets activities start
(offline, or with an output channel that keeps failing, starts back off).

:class:`Runner` starts, pauses, resumes, cancels and follows activities through their
managers and says so in the decision log; what to start and when is the choice's
business. The runner alone writes which activity is current and which is suspended: the
call that ends an activity (a cancel, its manager's last reply) clears it, and the
callers ask for a suspend or a restore rather than move activities themselves.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from datetime import datetime
from typing import Any

from activities import ActivityContext
from agenda import DueItem
from dms.config import ControllerSettings
from dms.controller.decisions import DecisionLog
from dms.controller.deps import ControllerDeps, Counters
from dms.controller.state import ActivityFacts
from dms.kernel.activity_names import ACTIVITIES, ManagerName, manager_of
from dms.kernel.messages import (
    Channel,
    ChosenBy,
    Reason,
    ScreenChoice,
    Speech,
    Touch,
    Why,
)
from managers import Manager, ManagerReply, ManagerStatus, make_managers


@dataclass
class Running:
    """The activity the controller believes runs, and why it was started."""

    name: str
    manager: ManagerName
    chosen_by: ChosenBy | None
    reason: Reason
    started: datetime
    user_id: str | None
    paused: bool = False
    agenda_item: DueItem | None = None

    def set_paused(self, paused: bool) -> None:
        """Its manager paused (or resumed) it: what ``dms/state`` and the choice see."""
        self.paused = paused


class Runner:
    """The current and the suspended activity, on their managers."""

    def __init__(
        self,
        deps: ControllerDeps,
        settings: ControllerSettings,
        log: DecisionLog,
        counters: Counters,
        context: Callable[[str], ActivityContext],
    ) -> None:
        """``context(name)`` makes the context an activity named ``name`` runs in."""
        self.deps = deps
        self.settings = settings
        self.log = log
        self.counters = counters
        self.context = context
        self.managers: dict[ManagerName, Manager] = make_managers(deps.library)
        self.current: Running | None = None
        self.suspended: Running | None = None
        """The activity a reminder paused, resumed when the reminder ends."""
        self.cleaning: set[ManagerName] = set()
        """Managers whose cancelled activities still run their cleanup states."""
        self.blocked = False
        """The robot is offline, or an output channel fails, and no probe is due: nothing
        starts (but what the user asks for by name)."""
        self.failing: Channel | None = None
        """The output channel whose commands keep failing, if any (``dms/state``)."""
        self._trouble: str | None = None
        """What the probes wait out: ``offline``, or the failing channel."""
        self._probe_at: float | None = None
        """Monotonic seconds of the next probe (a wall clock set back must not delay it)."""
        self._probe_wait_s = 0.0
        self.taken_at: datetime | None = None
        """When (steady time) the current activity last took words or a screen choice
        (an answer, or a try at one): an unanswered menu's time counts from then."""

    def start(
        self,
        name: str,
        reason: Reason,
        chosen_by: ChosenBy | None,
        now: datetime,
        user_id: str | None,
        detail: str | None = None,
        args: Mapping[str, Any] | None = None,
        agenda_item: DueItem | None = None,
        why: Why | None = None,
    ) -> bool:
        """Start ``name`` for ``user_id`` (None: nobody); False if it did not start."""
        # A failing channel holds the robot's own starts until the next probe, in silence,
        # but tries what the user asks for by name: she paces it, and it may work again.
        if self.blocked and not (self.failing is not None and reason == "user_request"):
            offline = self.failing is None
            if offline and (chosen_by == "user" or reason == "user_request"):
                # said, never dropped silently
                self.log.decide(
                    "fail", name, "activity_error", chosen_by, "the robot is offline", now
                )
            return False
        if name not in ACTIVITIES:  # removed from the catalogue, still named by a row
            self.log.decide("fail", name, "activity_error", chosen_by, "no such activity", now)
            return False
        manager = manager_of(name)
        reply = self.managers[manager].start(name, self.context(name), now, args)
        if reply.status is not ManagerStatus.RUNNING:
            self.counters.count_not_loaded()
            self.log.decide("fail", name, "activity_error", chosen_by, reply.detail, now)
            return False
        self.current = Running(
            name, manager, chosen_by, reason, now, user_id, agenda_item=agenda_item
        )
        self.log.decide("start", name, reason, chosen_by, detail, now, why)
        return True

    def pause(self, running: Running, reason: Reason, now: datetime, detail: str | None) -> bool:
        """Pause ``running``; False when its manager stopped it instead (an activity
        declared not pausable): then it is no longer current nor suspended, and the log
        says it was cancelled, and why, so nothing resumes it."""
        reply = self.managers[running.manager].pause(now)
        if reply.status is ManagerStatus.CANCELLED:
            if running is self.current:
                self.current = None
            elif running is self.suspended:
                self.suspended = None
            why = "; ".join(part for part in (detail, reply.detail) if part)
            self.log.decide("cancel", running.name, reason, running.chosen_by, why, now)
            return False
        running.set_paused(True)
        self.log.decide("pause", running.name, reason, running.chosen_by, detail, now)
        return True

    def resume(self, running: Running, reason: Reason, now: datetime, detail: str | None) -> None:
        self.managers[running.manager].resume(now)
        running.set_paused(False)
        self.log.decide("resume", running.name, reason, running.chosen_by, detail, now)

    def suspend(self, running: Running, reason: Reason, now: datetime, detail: str) -> None:
        """Pause the current ``running`` for a reminder: it waits as the suspended
        activity (one that cannot be paused is stopped: nothing waits), and nothing is
        current until the reminder starts."""
        if self.pause(running, reason, now, detail):
            self.suspended, self.current = running, None

    def set_aside(self) -> None:
        """A reminder interrupts a dialog: the current activity (paused for "continue or
        stop?", if any) waits as the suspended one, still paused."""
        self.suspended, self.current = self.current, None

    def restore(self) -> Running | None:
        """After the reminder: the suspended activity is current again (still paused: the
        caller resumes it, or asks "continue or stop?" again); returns it."""
        self.current, self.suspended = self.suspended, None
        return self.current

    def clear(self) -> None:
        """At shutdown, after the cancels: nothing runs any more, even what failed to
        cancel."""
        self.current = self.suspended = None

    def forget(self, running: Running) -> None:
        """The step following ``running`` failed: it is no longer current (the caller
        stops it on its manager and says why, each under the fault barrier)."""
        if running is self.current:
            self.current = None

    def failed(self, running: Running, detail: str | None, now: datetime) -> None:
        """``running`` failed while it ran: counted and said."""
        self.counters.count_failure()
        self.log.decide("fail", running.name, "activity_error", running.chosen_by, detail, now)

    def cancel(
        self,
        running: Running,
        reason: Reason,
        now: datetime,
        detail: str | None = None,
        cleanup: bool = True,
    ) -> ManagerReply:
        """Cancel ``running`` and say so; its cleanup states (SMACH's ``preempted``
        transitions) run on while the next activity starts, unless ``cleanup`` is off
        or it is the suspended activity (a reminder runs: it stops in silence)."""
        limit = self.settings.cleanup_limit_s
        quiet = not cleanup or limit <= 0 or running is self.suspended
        cleanup_s = None if quiet else limit
        # cleared once cancelled: while its manager cancels it (its cleanup states send
        # their first commands), it is still the run the robot's commands belong to; a
        # cancel that fails leaves it for the fault barrier's caller to abandon
        reply = self.managers[running.manager].cancel(now, cleanup_s)
        if running is self.current:
            self.current = None
        elif running is self.suspended:
            self.suspended = None
        if cleanup_s is not None and self.managers[running.manager].winding_down:
            self.cleaning.add(running.manager)
        self.log.decide("cancel", running.name, reason, running.chosen_by, detail, now)
        return reply

    def wind_down(self, now: datetime) -> None:
        """Tick the cleanup states of cancelled activities (also while a dialog is open)."""
        for name in list(self.cleaning):
            manager = self.managers[name]
            manager.wind_down(now)
            if not manager.winding_down:
                self.cleaning.discard(name)

    def follow(self, running: Running, now: datetime) -> ManagerReply:
        """Tick ``running``'s manager: what its activity did. An activity that ended
        (completed, failed, cancelled, or lost by its manager) is no longer current; a
        completion and a failure are said, as is a redirect to an unknown activity."""
        reply = self.managers[running.manager].tick(now)
        if reply.status in (ManagerStatus.RUNNING, ManagerStatus.PAUSED):
            return reply
        self.forget(running)
        if reply.status is ManagerStatus.FAILED:
            self.failed(running, reply.detail, now)
        elif reply.status is ManagerStatus.COMPLETED:
            chosen_by = running.chosen_by
            self.log.decide("complete", running.name, "completed", chosen_by, reply.detail, now)
            target = reply.redirect
            if target and target not in ACTIVITIES:
                detail = f"redirect to unknown {target!r}"
                self.log.decide("fail", running.name, "activity_error", chosen_by, detail, now)
        return reply

    def deliver(self, event: Touch) -> bool:
        """Hand a touch to the current activity; True if it took it."""
        running = self.current
        return running is not None and self.managers[running.manager].deliver(event)

    def take_words(self, event: Speech | ScreenChoice, steady: datetime) -> bool:
        """Hand words or a screen choice to the current activity at ``steady``; True if
        it took them (then :attr:`taken_at` says when)."""
        running = self.current
        if running is None or not self.managers[running.manager].deliver(event):
            return False
        self.taken_at = steady
        return True

    def published(self, running: Running | None) -> ActivityFacts | None:
        """What ``dms/state`` says of ``running``, taken now (its state path moves on)."""
        if running is None:
            return None
        activity = self.managers[running.manager].activity
        return ActivityFacts(
            name=running.name,
            manager=running.manager.value,
            status="paused" if running.paused else "running",
            state=activity.state_path if activity is not None else "",
        )

    def check_robot_link(self, monotonic: float) -> None:
        """Set :attr:`blocked`: True while the robot is offline and no probe is due.

        Offline (too many commands in a row not acknowledged), the robot starts nothing:
        an activity that only times out helps no one. Every so often one start is let
        through as a probe, the wait doubling from ``ack_timeout_s`` up to
        ``offline_retry_max_s``; feedback or the robot's token ends it at once. An output
        channel that keeps failing (:attr:`failing`) backs off the same way, so that a
        robot whose speech fails does not start and fail an activity every tick; a
        command done on it ends it.
        """
        self.failing = self.deps.expression.failing_channel
        self.blocked = self._unreachable(monotonic)

    def _unreachable(self, monotonic: float) -> bool:
        """Whether starts wait: the robot is offline, or an output channel keeps failing
        (then each start would only fail again: at most one is tried per probe)."""
        settings, expression = self.settings, self.deps.expression
        trouble = "offline" if expression.robot_offline else self.failing
        if trouble is None or (self._trouble is not None and trouble != self._trouble):
            if self._probe_at is not None:
                self._probe_at = None
                if self._trouble == "offline":
                    self.deps.report_error("robot", "robot back online: activities start again")
                else:
                    self.deps.report_error(
                        "robot", f"the {self._trouble} channel works again: activities start"
                    )
            self._trouble = None
            if trouble is None:
                return False
        if self._probe_at is None:
            self._trouble = trouble
            self._probe_wait_s = settings.ack_timeout_s
            self._probe_at = monotonic + self._probe_wait_s
            if trouble == "offline":
                self.deps.report_error(
                    "robot",
                    f"robot offline: {expression.unacked_in_a_row} commands in a row"
                    " not acknowledged; no activity starts until it answers",
                )
            elif self.failing is not None:
                failed = expression.failed_in_a_row.get(self.failing, 0)
                self.deps.report_error(
                    "robot",
                    f"the {self.failing} channel fails: {failed} commands in a row failed;"
                    " activities are tried again after a wait that doubles",
                )
            return True
        if monotonic < self._probe_at:
            return True
        self._probe_wait_s = min(2 * self._probe_wait_s, settings.offline_retry_max_s)
        self._probe_at = monotonic + self._probe_wait_s
        return False
