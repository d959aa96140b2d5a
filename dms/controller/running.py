"""The activity that runs, its managers, and the robot link that lets activities start.

:class:`Runner` starts, pauses, resumes and cancels activities through their managers
and says so in the decision log; what to start and when is the choice's business.
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
        """The robot is offline and no probe is due: nothing starts."""
        self._probe_at: float | None = None
        """Monotonic seconds of the next probe (a wall clock set back must not delay it)."""
        self._probe_wait_s = 0.0

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
        if self.blocked:
            if chosen_by == "user" or reason == "user_request":  # said, never dropped silently
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
            self.counters.not_loaded += 1
            self.log.decide("fail", name, "activity_error", chosen_by, reply.detail, now)
            return False
        self.current = Running(
            name, manager, chosen_by, reason, now, user_id, agenda_item=agenda_item
        )
        self.log.decide("start", name, reason, chosen_by, detail, now, why)
        return True

    def pause(self, running: Running, reason: Reason, now: datetime, detail: str | None) -> None:
        self.managers[running.manager].pause(now)
        running.paused = True
        self.log.decide("pause", running.name, reason, running.chosen_by, detail, now)

    def resume(self, running: Running, reason: Reason, now: datetime, detail: str | None) -> None:
        self.managers[running.manager].resume(now)
        running.paused = False
        self.log.decide("resume", running.name, reason, running.chosen_by, detail, now)

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
        reply = self.managers[running.manager].cancel(now, cleanup_s)
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

    def tick(self, running: Running, now: datetime) -> ManagerReply:
        """Tick ``running``'s manager: what its activity did."""
        return self.managers[running.manager].tick(now)

    def deliver(self, event: Speech | ScreenChoice | Touch) -> bool:
        """Hand an input to the current activity; True if it took it."""
        running = self.current
        return running is not None and self.managers[running.manager].deliver(event)

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
        ``offline_retry_max_s``; feedback or the robot's token ends it at once.
        """
        self.blocked = self._unreachable(monotonic)

    def _unreachable(self, monotonic: float) -> bool:
        settings, expression = self.settings, self.deps.expression
        if not expression.robot_offline:
            if self._probe_at is not None:
                self._probe_at = None
                self.deps.report_error("robot", "robot back online: activities start again")
            return False
        if self._probe_at is None:
            self._probe_wait_s = settings.ack_timeout_s
            self._probe_at = monotonic + self._probe_wait_s
            self.deps.report_error(
                "robot",
                f"robot offline: {expression.unacked_in_a_row} commands in a row"
                " not acknowledged; no activity starts until it answers",
            )
            return True
        if monotonic < self._probe_at:
            return True
        self._probe_wait_s = min(2 * self._probe_wait_s, settings.offline_retry_max_s)
        self._probe_at = monotonic + self._probe_wait_s
        return False
