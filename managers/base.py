"""The manager base: runs one activity of its group at a time and answers every command.

The paper's managers sit one level below the central controller: the controller
activates one, it starts the activity, and from then on every command (start, pause,
resume, cancel, tick) gets a status answer, a :class:`ManagerReply`. An activity that
raises is contained here: it is reported as failed, never brings the loop down.

A cancel with ``cleanup_s`` is SMACH's preemption: the activity's cleanup states run
on (``winding_down``) while the manager is already free for the next activity; the
controller ticks them with :meth:`Manager.wind_down` until they end or time runs out.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass, replace
from datetime import datetime
from enum import StrEnum
from typing import Any

from activities import Activity, ActivityContext, ActivityStatus, BehaviorLibrary
from dms.kernel.activity_names import ACTIVITIES, ManagerName, current
from dms.kernel.messages import ScreenChoice, Speech, Touch

log = logging.getLogger(__name__)


class ManagerStatus(StrEnum):
    """What a manager says about its activity after a command."""

    IDLE = "idle"
    """No activity: never started, or the last one ended and was collected."""
    RUNNING = "running"
    PAUSED = "paused"
    COMPLETED = "completed"
    """The activity reached its end; ``redirect`` may name the next activity."""
    FAILED = "failed"
    """The activity failed (a robot command timed out, a block raised...)."""
    CANCELLED = "cancelled"
    REFUSED = "refused"
    """The command made no sense now (start while busy, resume while running...)."""


@dataclass(frozen=True, slots=True)
class ManagerReply:
    """The status answer to one command."""

    manager: ManagerName
    activity: str | None
    status: ManagerStatus
    state: str = ""
    redirect: str | None = None
    detail: str | None = None
    data: Mapping[str, Any] | None = None


_FINAL = {
    ActivityStatus.COMPLETED: ManagerStatus.COMPLETED,
    ActivityStatus.FAILED: ManagerStatus.FAILED,
    ActivityStatus.CANCELLED: ManagerStatus.CANCELLED,
}


class Manager:
    """Runs the activities of one group; a subclass adds the group's partial decisions."""

    def __init__(self, name: ManagerName, library: BehaviorLibrary) -> None:
        self.name = name
        self._library = library
        self._activity: Activity | None = None
        self._activity_name: str | None = None
        self._winding_down: list[Activity] = []

    @property
    def activities(self) -> tuple[str, ...]:
        return tuple(name for name, manager in ACTIVITIES.items() if manager is self.name)

    @property
    def activity(self) -> Activity | None:
        return self._activity

    @property
    def activity_name(self) -> str | None:
        return self._activity_name

    @property
    def winding_down(self) -> tuple[Activity, ...]:
        """Cancelled activities whose cleanup states still run (oldest first)."""
        return tuple(self._winding_down)

    def _reply(
        self, status: ManagerStatus, detail: str | None = None, redirect: str | None = None
    ) -> ManagerReply:
        activity = self._activity
        data = (
            dict(activity.result.data)
            if activity is not None and status in _FINAL.values()
            else None
        )
        return ManagerReply(
            manager=self.name,
            activity=self._activity_name,
            status=status,
            state=activity.state_path if activity is not None else "",
            redirect=redirect,
            detail=detail,
            data=data,
        )

    def start(
        self, name: str, ctx: ActivityContext, now: datetime, args: Mapping[str, Any] | None = None
    ) -> ManagerReply:
        """Create and start ``name``; refused when it is not this manager's or one runs."""
        if ACTIVITIES.get(name) is not self.name:
            return ManagerReply(self.name, name, ManagerStatus.REFUSED, detail="not my activity")
        if self._activity is not None:
            return self._reply(ManagerStatus.REFUSED, detail=f"{self._activity_name} is running")
        for old in [a for a in self._winding_down if a.name == name]:  # one source per name
            self._stop_now(old, now)
        self._activity_name = name
        try:
            self._activity = self._library.create(name, ctx, args or {})
            self._activity.start(now)
        except Exception as error:  # a broken behavior must not stop the robot
            log.exception("activity %s did not start", name)
            self._activity = None
            return ManagerReply(
                self.name, name, ManagerStatus.FAILED, detail=f"not loaded: {error}"
            )
        return self._reply(ManagerStatus.RUNNING)

    def tick(self, now: datetime) -> ManagerReply:
        """Advance the activity; a final status is reported once, then the manager is idle."""
        activity = self._activity
        if activity is None:
            return ManagerReply(self.name, None, ManagerStatus.IDLE)
        try:
            status = activity.tick(now)
        except Exception as error:
            log.exception("activity %s raised", self._activity_name)
            return self._finish(ManagerStatus.FAILED, detail=f"{type(error).__name__}: {error}")
        if status in _FINAL:
            result = activity.result
            return self._finish(_FINAL[status], detail=result.error, redirect=result.redirect)
        if status is ActivityStatus.PAUSED:
            return self._reply(ManagerStatus.PAUSED)
        return self._reply(ManagerStatus.RUNNING)

    def _finish(
        self, status: ManagerStatus, detail: str | None = None, redirect: str | None = None
    ) -> ManagerReply:
        reply = self._reply(status, detail=detail, redirect=redirect)
        self._activity = None
        self._activity_name = None
        return reply

    def pause(self, now: datetime) -> ManagerReply:
        """Pause the activity; one declared not pausable is stopped instead (its reply
        is final, CANCELLED, and the manager is free)."""
        if self._activity is None:
            return ManagerReply(self.name, None, ManagerStatus.REFUSED, detail="nothing to pause")
        entry = current().entry(self._activity_name or "")
        if entry is not None and not entry.pausable:
            reply = self.cancel(now)
            return replace(reply, detail="it cannot be paused: stopped")
        self._activity.pause(now)
        return self._reply(ManagerStatus.PAUSED)

    def resume(self, now: datetime) -> ManagerReply:
        if self._activity is None:
            return ManagerReply(self.name, None, ManagerStatus.REFUSED, detail="nothing to resume")
        self._activity.resume(now)
        return self._reply(ManagerStatus.RUNNING)

    def cancel(self, now: datetime, cleanup_s: float | None = None) -> ManagerReply:
        """Stop the activity: at once, or (``cleanup_s``) letting its cleanup states run.

        Either way the reply is final and the manager is free: an activity still
        cleaning up moves to ``winding_down``, ticked by :meth:`wind_down`.
        """
        activity = self._activity
        if activity is None:
            return ManagerReply(self.name, None, ManagerStatus.IDLE)
        try:
            if cleanup_s is None:
                activity.cancel(now)
            else:
                activity.preempt(now, cleanup_s)
        except Exception as error:
            log.exception("activity %s raised on cancel", self._activity_name)
            self._stop_now(activity, now)
            return self._finish(ManagerStatus.CANCELLED, detail=f"{type(error).__name__}: {error}")
        if activity.stopping:
            self._winding_down.append(activity)
        return self._finish(ManagerStatus.CANCELLED)

    def wind_down(self, now: datetime) -> None:
        """Tick the cleanup states of cancelled activities; forget those that ended."""
        for activity in self._winding_down:
            try:
                activity.tick(now)
            except Exception:
                log.exception("activity %s raised while cleaning up", activity.name)
                self._stop_now(activity, now)
        self._winding_down = [a for a in self._winding_down if not a.finished]

    def stop_winding_down(self, now: datetime) -> None:
        """Cut every cleanup short (shutdown): stop at once."""
        for activity in self._winding_down:
            self._stop_now(activity, now)
        self._winding_down = []

    def _stop_now(self, activity: Activity, now: datetime) -> None:
        try:
            activity.cancel(now)
        except Exception:
            log.exception("activity %s raised when stopped", activity.name)
        if activity in self._winding_down:
            self._winding_down.remove(activity)

    def deliver(self, event: Speech | ScreenChoice | Touch) -> bool:
        """Offer a perception event to the activity; True if it took it (an answer)."""
        if self._activity is None:
            return False
        return self._activity.deliver(event)
