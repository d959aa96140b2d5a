"""Table 4 of the paper, measured by the daemon on each real session.

The paper's robot logged, per session, how long activities took to load and to run,
the time between them, who chose them, the cancels, the questions and the failures
(its logging list, row 17). :class:`SessionAccount` computes the same figures from
what the controller does: it is fed the controller's decisions and, once per tick,
the robot commands still pending, and is told ``now``; it does no I/O and reads no
clock. The controller stores :meth:`SessionAccount.result` with the session when the
session ends (the user left, or the daemon stops), and ``dms sessions`` reads them.

The definitions are those of ``sim/study.py`` (``SessionObserver``), so that a
deployment's table and a simulated study's can be set side by side:

- ``questions_per_session``: ``ask`` decisions with reason ``general_question``;
- ``activities_per_session``: activities started for the user (menus, notifications,
  waiting, sleeping and instructions are not what the user came for: not counted);
- ``activity_load_time_s``: from the ``start`` decision until the controller hears
  that the activity's first command sent to the robot started (the mean of the
  session's activities);
- ``activity_time_s``: from ``start`` to ``complete``, ``cancel`` or ``fail``;
- ``change_time_s``: from the end of one activity to the start of the next;
- ``robot_decisions_per_session`` / ``user_selections_per_session``: activities
  started ``chosen_by`` the robot / the user;
- ``cancels_per_session``: activities stopped by the user (``confirm_cancel``, or
  ``user_request``);
- failures: ``activity_not_loaded`` (``fail`` decisions whose detail says "not
  loaded"), ``speech_recognition_errors`` (utterances under the confidence the
  controller accepts), ``user_not_answering`` (dialogs that expired unanswered),
  ``other`` (other ``fail`` decisions of counted activities).

The three times are None for a session that has none to average.
"""

from __future__ import annotations

import statistics
from collections.abc import Callable, Sequence
from datetime import datetime

from dms.kernel.expression import CommandHandle
from dms.kernel.messages import Decision

NOT_COUNTED = frozenset({"menu", "notification", "wait", "sleep", "instructions"})
"""Activities that are not what the user came for (the paper counts entertainment)."""
USER_CANCEL_REASONS = frozenset({"confirm_cancel", "user_request"})
ACTIVITY_SOURCE = "activity:"
"""The prefix of the arbiter's ``source`` for an activity's commands."""

TIME_KEYS: tuple[str, ...] = ("activity_load_time_s", "activity_time_s", "change_time_s")
COUNT_KEYS: tuple[str, ...] = (
    "questions_per_session",
    "activities_per_session",
    "robot_decisions_per_session",
    "user_selections_per_session",
    "cancels_per_session",
)
FAILURE_KEYS: tuple[str, ...] = (
    "activity_not_loaded",
    "speech_recognition_errors",
    "user_not_answering",
    "other",
)
METRIC_KEYS: tuple[str, ...] = (
    "duration_s",
    "questions_per_session",
    "activities_per_session",
    "activity_load_time_s",
    "activity_time_s",
    "change_time_s",
    "robot_decisions_per_session",
    "user_selections_per_session",
    "cancels_per_session",
    *FAILURE_KEYS,
)
"""The keys of :meth:`SessionAccount.result`, in Table 4's order (``duration_s`` first)."""

Metrics = dict[str, float | int | None]
PendingCommands = Callable[[str], Sequence[CommandHandle]]
"""The arbiter's unfinished commands of one source (``ExpressionArbiter.pending``)."""


def _sent_order(handle: CommandHandle) -> tuple[datetime, int, str]:
    """Sort key: when the command was sent, then the arbiter's numbering (``cmd-N``)."""
    ident = handle.command_id or ""
    assert handle.sent_at is not None
    return handle.sent_at, len(ident), ident


class SessionAccount:
    """One session's Table 4, computed as it happens (see the module docstring).

    ``misheard`` and ``unanswered`` are the controller's running totals when the
    session began; :meth:`result` takes them again at the end and keeps the difference.
    """

    def __init__(self, started: datetime, *, misheard: int = 0, unanswered: int = 0) -> None:
        self.started = started
        self._misheard0 = misheard
        self._unanswered0 = unanswered
        self.questions = 0
        self.activities = 0
        self.robot_decisions = 0
        self.user_selections = 0
        self.cancels = 0
        self.not_loaded = 0
        self.other_failures = 0
        self.load_times: list[float] = []
        self.activity_times: list[float] = []
        self.change_times: list[float] = []
        self._started: dict[str, datetime] = {}
        self._loading: dict[str, tuple[datetime, CommandHandle | None]] = {}
        """Activities started (at the time given) whose first command has not started."""
        self._last_end: datetime | None = None

    def on_decision(self, decision: Decision, now: datetime) -> None:
        """Every decision the controller takes during the session, as it takes it."""
        name = decision.activity
        if decision.action == "ask" and decision.reason == "general_question":
            self.questions += 1
        if decision.action == "fail" and (decision.detail or "").startswith("not loaded"):
            self.not_loaded += 1
            return
        if name is None or name in NOT_COUNTED:
            return
        if decision.action == "start":
            self.activities += 1
            self._started[name] = now
            self._loading[name] = (now, None)
            if self._last_end is not None:
                self.change_times.append(_seconds(now, self._last_end))
                self._last_end = None
            if decision.chosen_by == "robot":
                self.robot_decisions += 1
            elif decision.chosen_by == "user":
                self.user_selections += 1
        elif decision.action in ("complete", "cancel", "fail"):
            self._loading.pop(name, None)  # ended before its first command started
            began = self._started.pop(name, None)
            if began is not None:
                self.activity_times.append(_seconds(now, began))
                self._last_end = now
            if decision.action == "cancel" and decision.reason in USER_CANCEL_REASONS:
                self.cancels += 1
            if decision.action == "fail":
                self.other_failures += 1

    def on_tick(self, now: datetime, pending: PendingCommands) -> None:
        """At the end of each tick: note each loading activity's first command sent, and
        count as loaded the activities whose first command the robot reported started.

        The controller reads the robot's feedback early in its tick, so a start seen
        now was heard at ``now``; a command sent in this tick is noted before any
        feedback on it can come.
        """
        if not self._loading:
            return  # most ticks: nothing is loading (no list to copy)
        for name, (began, handle) in list(self._loading.items()):
            if handle is None:
                sent = [h for h in pending(ACTIVITY_SOURCE + name) if h.sent_at is not None]
                if not sent:
                    continue
                handle = min(sent, key=_sent_order)
                self._loading[name] = (began, handle)
            if handle.started_at is not None:
                self.load_times.append(_seconds(now, began))
                del self._loading[name]
            elif handle.finished:
                del self._loading[name]  # failed or timed out: it never started

    def result(self, now: datetime, *, misheard: int = 0, unanswered: int = 0) -> Metrics:
        """The session's metrics at its end (``now``): plain JSON-able numbers, keyed by
        :data:`METRIC_KEYS`. ``misheard`` and ``unanswered``: the controller's totals now."""
        return {
            "duration_s": round(_seconds(now, self.started), 3),
            "questions_per_session": self.questions,
            "activities_per_session": self.activities,
            "activity_load_time_s": _mean(self.load_times),
            "activity_time_s": _mean(self.activity_times),
            "change_time_s": _mean(self.change_times),
            "robot_decisions_per_session": self.robot_decisions,
            "user_selections_per_session": self.user_selections,
            "cancels_per_session": self.cancels,
            "activity_not_loaded": self.not_loaded,
            "speech_recognition_errors": max(0, misheard - self._misheard0),
            "user_not_answering": max(0, unanswered - self._unanswered0),
            "other": self.other_failures,
        }


def _seconds(later: datetime, earlier: datetime) -> float:
    return (later - earlier).total_seconds()


def _mean(values: list[float]) -> float | None:
    return round(statistics.fmean(values), 3) if values else None
