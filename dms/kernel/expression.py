"""Expression arbitration (the paper's expression manager): one command per channel.

Activities and the controller's dialogs ask for robot commands through
:meth:`ExpressionArbiter.request` and get a :class:`CommandHandle` whose status they
watch. The arbiter sends at most one command per channel (speech, screen, led, motion,
media) at a time, so commands from several sources never collide: the others wait in
a queue ordered by priority, then by arrival. A HIGH-priority command (a notification,
the controller's "continue or stop?") preempts a NORMAL one on its channel; the
interrupted command goes back to the head of the queue and is sent again, from the
start, once the channel is free (when the interrupted source resumes).

A command the robot never acknowledges is timed out after ``ack_timeout_s``, and one it
started but never finished after ``done_timeout_s`` (plus the ``duration_s`` of media
that says how long it lasts): its handle ends ``timed_out`` and the activity that issued
it fails cleanly. The waits are measured on the monotonic clock the controller's tick
hands over (:meth:`ExpressionArbiter.set_monotonic`), so a wall clock set forward fails
no command in flight; an arbiter never handed one measures on the wall clock.

The ``aim`` channel (gaze and pointing toward a frame) is best effort: a robot that
predates it may ignore its commands, so their going unacknowledged never counts
toward :attr:`ExpressionArbiter.robot_offline`, and the blocks that send them go on
without them. It has its own lane, so it never holds up the gestures of ``motion``.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from datetime import datetime, timedelta
from enum import IntEnum, StrEnum
from typing import Any

from dms.kernel.messages import Channel, RobotCommand
from dms.kernel.ports import RobotPort

BEST_EFFORT_CHANNELS = frozenset({"aim"})
"""Channels whose silence says nothing about the robot being there."""
FAILING_AFTER = 2
"""Commands in a row the robot reports failed on one channel before it counts as failing:
one failure may be a passing hitch; a second in a row, with nothing done between, is a
channel that does not work (the controller then backs off, starting activities seldom)."""


class Priority(IntEnum):
    """How urgently a command wants its channel."""

    NORMAL = 0
    """Activities: waits its turn, may be preempted."""
    HIGH = 1
    """Notifications and the controller's dialogs: preempts NORMAL commands."""


class CommandStatus(StrEnum):
    """Where a requested command stands."""

    QUEUED = "queued"
    """Waiting for its channel (or preempted and waiting to be repeated)."""
    SENT = "sent"
    """Sent to the robot, not yet acknowledged."""
    STARTED = "started"
    """The robot reported it started."""
    DONE = "done"
    """The robot reported it finished."""
    INTERRUPTED = "interrupted"
    """Withdrawn by its source (or stopped by the robot) before it finished."""
    FAILED = "failed"
    """The robot reported it could not execute it."""
    TIMED_OUT = "timed_out"
    """The robot never acknowledged it, or never finished it, in time."""


FINAL_STATUSES = frozenset(
    {CommandStatus.DONE, CommandStatus.INTERRUPTED, CommandStatus.FAILED, CommandStatus.TIMED_OUT}
)


@dataclass(eq=False)
class CommandHandle:
    """One requested command: what its source watches until it is final."""

    source: str
    channel: Channel
    action: str
    args: dict[str, Any]
    priority: Priority
    status: CommandStatus = CommandStatus.QUEUED
    command_id: str | None = None
    """The id of the last send (a repeated command gets a new id)."""
    sent_at: datetime | None = None
    started_at: datetime | None = None
    sends: int = 0
    detail: str | None = None
    order: int = 0
    sent_monotonic: float | None = None
    """Monotonic seconds of the last send, for its timeout (None: measured on ``sent_at``)."""
    started_monotonic: float | None = None
    """Monotonic seconds of the robot's "started", likewise."""

    @property
    def finished(self) -> bool:
        """True once the status is final (done, interrupted, failed, timed out)."""
        return self.status in FINAL_STATUSES

    @property
    def ok(self) -> bool:
        return self.status is CommandStatus.DONE


@dataclass
class _Channel:
    active: CommandHandle | None = None
    queue: list[CommandHandle] = field(default_factory=list)


class ExpressionArbiter:
    """Serialises robot commands per channel; see the module docstring."""

    def __init__(
        self,
        robot: RobotPort,
        on_command: Callable[[RobotCommand], None],
        ack_timeout_s: float = 10.0,
        done_timeout_s: float = 120.0,
        offline_after_unacked: int = 3,
    ) -> None:
        self.robot = robot
        self.on_command = on_command
        self.ack_timeout = timedelta(seconds=ack_timeout_s)
        self.done_timeout = timedelta(seconds=done_timeout_s)
        self._channels: dict[str, _Channel] = {}
        self._by_id: dict[str, CommandHandle] = {}
        self._ids = itertools.count(1)
        self._order = itertools.count()
        self.sent = 0
        self.preemptions = 0
        self.timeouts = 0
        self.offline_after_unacked = offline_after_unacked
        self.unacked_in_a_row = 0
        """Commands the robot never acknowledged since it last said anything."""
        self.failed_in_a_row: dict[Channel, int] = {}
        """By channel: commands the robot reported failed since one last was done."""
        self._seen = False  # set from a bus thread by robot_seen(), read by update()
        self._monotonic: float | None = None

    def set_monotonic(self, monotonic: float) -> None:
        """The controller's tick, first: the monotonic seconds that commands sent, started
        and timed out from now on are stamped and measured with."""
        self._monotonic = monotonic

    # ------------------------------------------------------------ requests

    def request(
        self,
        source: str,
        channel: Channel,
        action: str,
        args: Mapping[str, Any],
        now: datetime,
        priority: Priority = Priority.NORMAL,
    ) -> CommandHandle:
        """Queue a command for ``channel``; it is sent at once if the channel is free."""
        handle = CommandHandle(
            source, channel, action, dict(args), priority, order=next(self._order)
        )
        lane = self._channels.setdefault(channel, _Channel())
        active = lane.active
        if active is not None and priority > active.priority:
            self._preempt(lane, active, now)
        lane.queue.append(handle)
        lane.queue.sort(key=lambda h: (-h.priority, h.order))
        self._dispatch(lane, now)
        return handle

    def interrupt(self, handle: CommandHandle, now: datetime) -> None:
        """Withdraw one command: dequeue it, or stop it on the robot."""
        self._withdraw(handle, now)
        lane = self._channels.get(handle.channel)
        if lane is not None:
            self._dispatch(lane, now)

    def _withdraw(self, handle: CommandHandle, now: datetime) -> None:
        if handle.finished:
            return
        lane = self._channels.get(handle.channel)
        if lane is None:
            return
        if handle in lane.queue:
            lane.queue.remove(handle)
        if lane.active is handle:
            lane.active = None
            if handle.command_id is not None:
                self._by_id.pop(handle.command_id, None)
                self.robot.interrupt(handle.command_id, now)
        handle.status = CommandStatus.INTERRUPTED

    def interrupt_source(self, source: str, now: datetime) -> None:
        """Withdraw every queued and running command of ``source``."""
        for lane in list(self._channels.values()):
            mine = [h for h in [*lane.queue, lane.active] if h is not None and h.source == source]
            for handle in mine:
                self._withdraw(handle, now)
            self._dispatch(lane, now)

    def active(self, channel: str) -> CommandHandle | None:
        """The command the robot is executing on ``channel``, if any."""
        lane = self._channels.get(channel)
        return lane.active if lane is not None else None

    def pending(self, source: str | None = None) -> list[CommandHandle]:
        """Unfinished commands (of ``source``), running ones first."""
        out: list[CommandHandle] = []
        for lane in self._channels.values():
            for handle in [lane.active, *lane.queue]:
                if handle is not None and (source is None or handle.source == source):
                    out.append(handle)
        return out

    # ------------------------------------------------------------ the robot

    @property
    def robot_offline(self) -> bool:
        """True once :attr:`offline_after_unacked` commands in a row went unacknowledged,
        until the robot says anything again (feedback, or its liveliness token)."""
        return self.unacked_in_a_row >= self.offline_after_unacked

    @property
    def failing_channel(self) -> Channel | None:
        """The channel whose last :data:`FAILING_AFTER` commands (or more) all failed, until
        one is done on it; the first in alphabetical order if several fail."""
        failing = sorted(c for c, n in self.failed_in_a_row.items() if n >= FAILING_AFTER)
        return failing[0] if failing else None

    def robot_seen(self) -> None:
        """The robot's liveliness token came (back): it is reachable. Any thread."""
        self._seen = True

    def update(self, now: datetime) -> None:
        """Collect the robot's feedback, time out silent commands, send what can go."""
        if self._seen:
            self._seen = False
            self.unacked_in_a_row = 0
        for feedback in self.robot.poll(now):
            self.unacked_in_a_row = 0  # even late feedback shows the robot is there
            handle = self._by_id.get(feedback.id)
            if handle is None or handle.command_id != feedback.id or handle.finished:
                continue
            if feedback.status == "started":
                handle.status = CommandStatus.STARTED
                handle.started_at = now
                handle.started_monotonic = self._monotonic
                continue
            self._by_id.pop(feedback.id, None)
            if feedback.status == "failed" and handle.channel not in BEST_EFFORT_CHANNELS:
                failed = self.failed_in_a_row.get(handle.channel, 0)
                self.failed_in_a_row[handle.channel] = failed + 1
            elif feedback.status == "done":
                self.failed_in_a_row.pop(handle.channel, None)
            handle.detail = feedback.detail
            handle.status = {
                "done": CommandStatus.DONE,
                "interrupted": CommandStatus.INTERRUPTED,
                "failed": CommandStatus.FAILED,
            }[feedback.status]
            self._release(handle, now)
        for lane in self._channels.values():
            active = lane.active
            if active is None:
                continue
            overdue = self._overdue(active, now)
            if overdue is not None:
                self.timeouts += 1
                if (
                    active.status is CommandStatus.SENT
                    and active.channel not in BEST_EFFORT_CHANNELS
                ):
                    self.unacked_in_a_row += 1
                active.status = CommandStatus.TIMED_OUT
                active.detail = overdue
                if active.command_id is not None:
                    self._by_id.pop(active.command_id, None)
                    self.robot.interrupt(active.command_id, now)
                lane.active = None
        for lane in self._channels.values():
            if lane.active is None and lane.queue:
                self._dispatch(lane, now)

    def _overdue(self, active: CommandHandle, now: datetime) -> str | None:
        """Why ``active`` has waited too long for the robot, or None."""
        if active.status is CommandStatus.SENT and active.sent_at is not None:
            waited = self._waited(active.sent_at, active.sent_monotonic, now)
            if waited >= self.ack_timeout:
                return f"not acknowledged within {self.ack_timeout.total_seconds():g} s"
        elif active.status is CommandStatus.STARTED and active.started_at is not None:
            waited = self._waited(active.started_at, active.started_monotonic, now)
            if waited < self.done_timeout:
                return None  # within the shortest limit: no need to work out this one's
            length = active.args.get("duration_s")
            extra = float(length) if isinstance(length, int | float) and length > 0 else 0.0
            limit = self.done_timeout + timedelta(seconds=extra)
            if waited >= limit:
                return f"started but not done within {limit.total_seconds():g} s"
        return None

    def _waited(self, since: datetime, since_monotonic: float | None, now: datetime) -> timedelta:
        """How long since ``since``: on the monotonic clock if both ends were stamped on it."""
        if since_monotonic is not None and self._monotonic is not None:
            return timedelta(seconds=self._monotonic - since_monotonic)
        return now - since

    def _release(self, handle: CommandHandle, now: datetime) -> None:
        lane = self._channels.get(handle.channel)
        if lane is not None and lane.active is handle:
            lane.active = None
            self._dispatch(lane, now)

    def _preempt(self, lane: _Channel, active: CommandHandle, now: datetime) -> None:
        """Stop ``active`` for a more urgent command; it is queued again to be repeated."""
        self.preemptions += 1
        if active.command_id is not None:
            self._by_id.pop(active.command_id, None)
            self.robot.interrupt(active.command_id, now)
        lane.active = None
        active.status = CommandStatus.QUEUED
        lane.queue.append(active)

    def _dispatch(self, lane: _Channel, now: datetime) -> None:
        if lane.active is not None or not lane.queue:
            return
        lane.queue.sort(key=lambda h: (-h.priority, h.order))
        handle = lane.queue.pop(0)
        command_id = f"cmd-{next(self._ids)}"
        handle.command_id = command_id
        handle.sends += 1
        handle.sent_at = now
        handle.sent_monotonic = self._monotonic
        handle.status = CommandStatus.SENT
        lane.active = handle
        self._by_id[command_id] = handle
        command = RobotCommand(
            id=command_id, channel=handle.channel, action=handle.action, args=handle.args
        )
        self.sent += 1
        self.on_command(command)
        self.robot.send(command, now)
