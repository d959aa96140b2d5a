"""``dms sim study``: the seed's first experiment with simulated participants.

N participants (default 30) each sit in front of the robot for M minutes (default 30),
one after the other, on one robot with one store, as in the seed's usability study:
the robot asks a few general questions, then activities follow, chosen by the robot or
by the participant according to the participant's proactivity (moderate, as in the
paper, unless ``--proactivity`` says otherwise). Each participant is one of the shipped
personas with its preferences and habits jittered, so no two are alike.

The metrics are those of the seed's Table 4, measured on what the controller decided
and the simulated robot did:

- questions per session: general questions asked (``ask`` decisions, reason
  ``general_question``);
- activities per session: activities started for the participant (menus,
  notifications, waiting and sleeping not counted);
- activity loading time: from the ``start`` decision until the controller hears from
  the robot that the activity's first command started (its ``started`` feedback): the
  wait for the channel (a dialog or another command still speaking) plus the feedback
  round, which the controller reads at its next update (0 or one tick; see
  docs/simulation.md for why it is smaller than the paper's);
- activity execution time: from ``start`` to ``complete``, ``cancel`` or ``fail``;
- time to change activity: from the end of one activity to the start of the next
  (feedback question, menus and general questions in between);
- robot decisions / user selections: activities started by the robot (predicted
  preferences) / by the participant (menu, by name);
- cancels: activities stopped by the participant (shoulder dialog or by asking for another);
- failures (totals over all sessions): activities that did not load, utterances the
  recognizer got wrong, questions left unanswered, other activity failures.
"""

from __future__ import annotations

import random
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import UTC, datetime
from typing import Any, Literal

from dms.config import Settings
from dms.expression import CommandHandle
from dms.messages import RobotCommand
from sim.harness import Simulation, TimedDecision
from sim.persona import Persona, Preferences, load_persona, shipped_personas
from sim.user import SimulatedUser

NOT_COUNTED = frozenset({"menu", "notification", "wait", "sleep", "instructions"})
"""Activities that are not what the participant came for (the paper counts entertainment)."""
USER_CANCEL_REASONS = frozenset({"confirm_cancel", "user_request"})
ACTIVITY_SOURCE = "activity:"
"""The prefix of the arbiter's ``source`` for an activity's commands."""
GAP_S = 120.0
"""Virtual seconds between two participants."""

ProactivityLevel = Literal["low", "moderate", "high"]


@dataclass
class SessionMetrics:
    """Table 4's figures for one session."""

    questions: int = 0
    activities: int = 0
    load_times: list[float] = field(default_factory=list)
    activity_times: list[float] = field(default_factory=list)
    change_times: list[float] = field(default_factory=list)
    robot_decisions: int = 0
    user_selections: int = 0
    cancels: int = 0
    not_loaded: int = 0
    misrecognized: int = 0
    unanswered: int = 0
    other_failures: int = 0


class SessionObserver:
    """Turns one session's decisions and robot commands into :class:`SessionMetrics`."""

    def __init__(self) -> None:
        self.metrics = SessionMetrics()
        self._started: dict[str, float] = {}
        self._first: dict[str, CommandHandle] = {}
        """Per activity, its first command sent since its last start or end."""
        self._loading: dict[str, tuple[float, CommandHandle | None]] = {}
        """Activities started (at t) whose first command has not started yet."""
        self._last_end: float | None = None

    def on_decision(self, timed: TimedDecision) -> None:
        d, t, m = timed.decision, timed.t, self.metrics
        name = d.activity
        if d.action == "ask" and d.reason == "general_question":
            m.questions += 1
        counted = name is not None and name not in NOT_COUNTED
        if d.action == "fail" and (d.detail or "").startswith("not loaded"):
            m.not_loaded += 1
            return
        if not counted or name is None:
            return
        if d.action == "start":
            m.activities += 1
            self._started[name] = t
            # Decisions are reported after their tick: the activity may have sent its
            # first command in the tick that started it.
            self._loading[name] = (t, self._first.pop(name, None))
            if self._last_end is not None:
                m.change_times.append(t - self._last_end)
                self._last_end = None
            if d.chosen_by == "robot":
                m.robot_decisions += 1
            elif d.chosen_by == "user":
                m.user_selections += 1
        elif d.action in ("complete", "cancel", "fail"):
            self._first.pop(name, None)
            self._loading.pop(name, None)  # ended before its first command started
            began = self._started.pop(name, None)
            if began is not None:
                m.activity_times.append(t - began)
                self._last_end = t
            if d.action == "cancel" and d.reason in USER_CANCEL_REASONS:
                m.cancels += 1
            if d.action == "fail":
                m.other_failures += 1

    def on_command(self, handle: CommandHandle | None, t: float) -> None:
        """A command was sent to the robot; ``handle`` is the arbiter's, with its source."""
        if handle is None or not handle.source.startswith(ACTIVITY_SOURCE):
            return
        name = handle.source[len(ACTIVITY_SOURCE) :]
        loading = self._loading.get(name)
        if loading is not None and loading[1] is None:
            self._loading[name] = (loading[0], handle)
        elif loading is None:
            self._first.setdefault(name, handle)

    def on_tick(self, t: float) -> None:
        """After each tick: an activity whose first command the robot reports started is loaded.

        The controller reads the robot's feedback during its tick, so a ``started_at``
        seen now was set in this tick, at ``t``.
        """
        for name, (began, handle) in list(self._loading.items()):
            if handle is None:
                continue
            if handle.started_at is not None:
                self.metrics.load_times.append(t - began)
                del self._loading[name]
            elif handle.finished:
                del self._loading[name]  # failed or timed out: it never started


def command_handle(sim: Simulation, command: RobotCommand) -> CommandHandle | None:
    """The arbiter's handle of ``command``, told to listeners as it is being sent."""
    handle = sim.stack.expression.active(command.channel)
    return handle if handle is not None and handle.command_id == command.id else None


def participant(base: Persona, index: int, rng: random.Random, level: ProactivityLevel) -> Persona:
    """A participant: ``base`` with jittered preferences and habits and the study's proactivity."""
    prefs = {
        name: min(1.0, max(0.0, value + rng.gauss(0.0, 0.15)))
        for name, value in base.preferences.model_dump().items()
    }
    speech = base.speech.model_copy(
        update={"error_rate": min(1.0, max(0.0, base.speech.error_rate * rng.uniform(0.5, 1.5)))}
    )
    return base.model_copy(
        update={
            "name": f"p{index:02d}",
            "user_id": f"p{index:02d}",
            "preferences": Preferences(**prefs),
            "proactivity": level,
            "speech": speech,
            "features": {**base.features, "proactivity": level},
        }
    )


@dataclass
class StudyResult:
    sessions: list[SessionMetrics]
    wall_s: float
    minutes: float
    proactivity: str
    seed: int

    def to_json(self) -> dict[str, Any]:
        """CONTRACT.md's keys (per-session means), plus their standard deviations."""
        rows = _rows(self.sessions)
        out: dict[str, Any] = {"sessions": len(self.sessions)}
        std: dict[str, float] = {}
        for key, (mean, sd) in rows.items():
            out[key] = round(mean, 3)
            std[key] = round(sd, 3)
        out["failures"] = _failures(self.sessions)
        out["wall_s"] = round(self.wall_s, 3)
        out["std"] = std
        out["minutes"] = self.minutes
        out["proactivity"] = self.proactivity
        out["seed"] = self.seed
        return out

    def table(self) -> str:
        """The seed's Table 4 for this simulated run."""
        rows = _rows(self.sessions)
        fails = _failures(self.sessions)
        lines = [
            f"Table 4 (simulated): {len(self.sessions)} sessions of {self.minutes:g} min, "
            f"proactivity {self.proactivity}, seed {self.seed}",
            f"{'Metric type':<15} {'Metric':<38} Values",
            "-" * 70,
        ]
        for key, label, kind in _TABLE:
            if kind == "failure":
                value = str(fails[key])
            else:
                mean, sd = rows[key]
                value = f"{mean:.2f} ({sd:.2f})"
            lines.append(f"{kind_label(kind):<15} {label:<38} {value}")
        lines.append(f"({self.wall_s:.1f} s wall time)")
        return "\n".join(lines)


def kind_label(kind: str) -> str:
    return {"performance": "Performance", "functions": "DMS functions", "failure": "Failures"}[kind]


_TABLE = (
    ("questions_per_session", "Questions per session", "performance"),
    ("activities_per_session", "Activities per session", "performance"),
    ("activity_load_time_s", "Activity average loading time (s)", "performance"),
    ("activity_time_s", "Activity execution average time (s)", "performance"),
    ("change_time_s", "Average time to change activity (s)", "performance"),
    ("robot_decisions_per_session", "Robot autonomous decisions", "functions"),
    ("user_selections_per_session", "User activities selection", "functions"),
    ("cancels_per_session", "Cancel ongoing activity", "functions"),
    ("activity_not_loaded", "Activity not loaded", "failure"),
    ("speech_recognition_errors", "Speech recognition errors", "failure"),
    ("user_not_answering", "User not answering", "failure"),
    ("other", "Other DMS errors", "failure"),
)


def _mean(values: list[float]) -> float:
    return statistics.fmean(values) if values else 0.0


def _stats(values: list[float]) -> tuple[float, float]:
    if not values:
        return 0.0, 0.0
    return statistics.fmean(values), statistics.pstdev(values) if len(values) > 1 else 0.0


def _rows(sessions: list[SessionMetrics]) -> dict[str, tuple[float, float]]:
    return {
        "questions_per_session": _stats([float(s.questions) for s in sessions]),
        "activities_per_session": _stats([float(s.activities) for s in sessions]),
        "activity_load_time_s": _stats([_mean(s.load_times) for s in sessions if s.load_times]),
        "activity_time_s": _stats([_mean(s.activity_times) for s in sessions if s.activity_times]),
        "change_time_s": _stats([_mean(s.change_times) for s in sessions if s.change_times]),
        "robot_decisions_per_session": _stats([float(s.robot_decisions) for s in sessions]),
        "user_selections_per_session": _stats([float(s.user_selections) for s in sessions]),
        "cancels_per_session": _stats([float(s.cancels) for s in sessions]),
    }


def _failures(sessions: list[SessionMetrics]) -> dict[str, int]:
    return {
        "activity_not_loaded": sum(s.not_loaded for s in sessions),
        "speech_recognition_errors": sum(s.misrecognized for s in sessions),
        "user_not_answering": sum(s.unanswered for s in sessions),
        "other": sum(s.other_failures for s in sessions),
    }


def run_study(
    sessions: int = 30,
    minutes: float = 30.0,
    proactivity: ProactivityLevel = "moderate",
    seed: int = 0,
    settings: Settings | None = None,
    progress: Callable[[int], None] | None = None,
) -> StudyResult:
    """Run the study on the virtual clock; ``progress`` is told of each finished session."""
    wall = time.perf_counter()
    rng = random.Random(seed)
    bases = [load_persona(name) for name in shipped_personas() if name != "demo"]
    results: list[SessionMetrics] = []
    start = datetime(2026, 11, 23, 9, 0, tzinfo=UTC)
    with Simulation(settings, seed=seed, start=start) as sim:
        sim.idle_step_s = 10.0  # between participants nobody is there (see sim.harness)
        observer = SessionObserver()
        sim.decision_listeners.append(lambda timed: observer.on_decision(timed))
        sim.command_listeners.append(
            lambda cmd, now: observer.on_command(command_handle(sim, cmd), sim.t)
        )
        sim.tick_listeners.append(lambda _record: observer.on_tick(sim.t))
        for index in range(1, sessions + 1):
            person = participant(rng.choice(bases), index, rng, proactivity)
            user = SimulatedUser(person, random.Random(rng.random()))
            observer = SessionObserver()
            unanswered_before = sim.controller.counters.unanswered
            sim.seat(user)
            sim.run_for(minutes * 60.0)
            sim.unseat()
            sim.run_for(1.0)  # the departure is seen and the session closed
            metrics = observer.metrics
            metrics.misrecognized = user.stats.misrecognized
            metrics.unanswered = sim.controller.counters.unanswered - unanswered_before
            observer = SessionObserver()  # the gap between participants is not measured
            sim.run_for(GAP_S)
            results.append(metrics)
            if progress is not None:
                progress(index)
    return StudyResult(results, time.perf_counter() - wall, minutes, proactivity, seed)
