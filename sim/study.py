"""``dms sim study``: the seed's first experiment with simulated participants.

N participants (default 30) each sit in front of the robot for M minutes (default 30),
one after the other, on one robot with one store, as in the seed's usability study:
the robot asks a few general questions, then activities follow, chosen by the robot or
by the participant according to the participant's proactivity (moderate, as in the
paper, unless ``--proactivity`` says otherwise), until the last one that fits before the
survey at the end. Each participant is an adult like the seed's (:mod:`sim.population`)
or, with ``--population personas``, a shipped persona with its preferences and habits
jittered, so no two are alike.

The metrics are those of the seed's Table 4, measured on what the controller decided
and the simulated robot did:

- questions per session: general questions asked (``ask`` decisions, reason
  ``general_question``);
- activities per session: activities started for the participant (menus,
  notifications, waiting and sleeping not counted) until their last one
  (:data:`LAST_CALL_S`);
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
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
from typing import Any, Literal

from dms.config import Settings
from dms.kernel.expression import CommandHandle
from dms.kernel.messages import Decision, RobotCommand
from sim.harness import Simulation, TimedDecision
from sim.persona import Persona, Preferences, load_persona, shipped_personas
from sim.population import INITIATIVE_ANSWER, paper_participant
from sim.user import SimulatedUser, UserStats

NOT_COUNTED = frozenset({"menu", "notification", "wait", "sleep", "instructions"})
"""Activities that are not what the participant came for (the paper counts entertainment)."""
USER_CANCEL_REASONS = frozenset({"confirm_cancel", "user_request"})
ACTIVITY_SOURCE = "activity:"
"""The prefix of the arbiter's ``source`` for an activity's commands."""
GAP_S = 120.0
"""Virtual seconds between two participants."""
SURVEY_S = 180.0
"""The seed's usability survey at the end of each 30-minute session ("around 3 min")."""
LAST_CALL_S = 255.91 + 43.12
"""What one more activity needs: the seed's mean execution time and time to change
activity (Table 4). An activity that ends with less than this left before the survey is
the participant's last, and they get up for the survey when the robot moves on: the
seed's participants did the survey "after completing the activities" ("Experimental
setup"), so the survey cut none. The seed's figures agree: 4.76 activities of 255.9 s,
3.8 s to load each and 43.1 s between them take 23.3 minutes, about 2.7 minutes less
than the 27 before the survey leave after the opening questions and the first choice
(about a minute): half of what one more activity needs, what stopping at the last
activity that fits leaves on average. Cutting the activity under way at the survey and
counting it instead gave about one activity a session too many (it began with minutes
left) and an execution time that matched only because the cut ones were short."""
LAUNCH_DELAY_S = (3.0, 3.8)
"""The simulated Mini's time to launch an activity's process (uniform, seconds). The
seed's loading time, 3.78 s (SD 0.25), is this plus the feedback round of up to one
tick (0.5 s), so the launch is set a little under it."""
Population = Literal["paper", "personas"]

ProactivityLevel = Literal["low", "moderate", "high"]


@dataclass
class SessionMetrics:
    """Table 4's figures for one session."""

    participant: str = ""
    visit: int = 1
    """Which time this participant comes (``--repeat``)."""
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
    robot_choice_cancels: int = 0
    """Cancels (by the participant) of activities the robot chose."""
    kendall_tau: float | None = None
    """After the session: the daemon's predicted ranking against the participant's true one."""


class SessionObserver:
    """Turns one session's decisions and robot commands into :class:`SessionMetrics`.

    With ``last_call`` (a virtual second), the activity that ends at or after it is the
    participant's last (the study's protocol, :data:`LAST_CALL_S`): nothing after its end
    is measured, and :attr:`finished` turns true when the robot moves on (starts a menu or
    another activity), when the participant gets up for the survey. Without it, every
    decision until the participant leaves is measured.
    """

    def __init__(self, last_call: float | None = None) -> None:
        self.metrics = SessionMetrics()
        self.last_call = last_call
        self.finished = False
        """The participant's activities are over (only with ``last_call``)."""
        self._closing = False
        """The last activity has ended: what the robot starts next is not measured."""
        self._started: dict[str, float] = {}
        self._first: dict[str, CommandHandle] = {}
        """Per activity, its first command sent since its last start or end."""
        self._loading: dict[str, tuple[float, CommandHandle | None]] = {}
        """Activities started (at t) whose first command has not started yet."""
        self._last_end: float | None = None

    def on_decision(self, timed: TimedDecision) -> None:
        d, t, m = timed.decision, timed.t, self.metrics
        name = d.activity
        if self.finished:
            return
        if self._closing and d.action == "start":
            self.finished = True  # the participant gets up instead
            return
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
                if d.chosen_by == "robot":
                    m.robot_choice_cancels += 1
            if d.action == "fail":
                m.other_failures += 1
            if self.last_call is not None and t >= self.last_call and d.reason != "user_left":
                self._closing = True

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
        if not self._loading:
            return  # most ticks: nothing is loading (no list to copy)
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
    """A participant from a shipped persona: ``base`` with jittered preferences and habits
    and the study's proactivity (``--population personas``)."""
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
            "decline_menu_rate": None,
            "answers": {"how often should i start": INITIATIVE_ANSWER[level]},
            "speech": speech,
            "features": {**base.features},
        }
    )


def participants(
    count: int, seed: int, level: ProactivityLevel, population: Population = "paper"
) -> list[Persona]:
    """The study's participants, drawn from their own generator: the same seed gives the
    same people whatever design runs (``dms sim compare`` pairs sessions on them)."""
    rng = random.Random(f"participants/{seed}")
    if population == "paper":
        return [paper_participant(index, rng, level) for index in range(1, count + 1)]
    bases = [load_persona(name) for name in shipped_personas() if name != "demo"]
    return [participant(rng.choice(bases), index, rng, level) for index in range(1, count + 1)]


PAPER: dict[str, tuple[float, float]] = {
    "questions_per_session": (3.78, 0.56),
    "activities_per_session": (4.76, 0.42),
    "activity_load_time_s": (3.78, 0.25),
    "activity_time_s": (255.91, 62.89),
    "change_time_s": (43.12, 3.21),
    "robot_decisions_per_session": (2.30, 0.26),
    "user_selections_per_session": (2.46, 0.18),
    "cancels_per_session": (0.53, 0.09),
}
"""The seed's Table 4: mean (SD) per session of the eight metrics."""
PAPER_FAILURES: dict[str, int] = {
    "activity_not_loaded": 2,
    "speech_recognition_errors": 5,
    "user_not_answering": 0,
    "other": 1,
}
"""The seed's Table 4 failures: totals over its 30 sessions."""
METRICS: tuple[str, ...] = tuple(PAPER)


@dataclass
class DecisionRow:
    """One decision of the study, for ``decisions.csv``."""

    session: int
    participant: str
    visit: int
    t: float
    """Seconds since the participant sat down."""
    decision: Decision


@dataclass
class StudyResult:
    sessions: list[SessionMetrics]
    wall_s: float
    minutes: float
    proactivity: str
    seed: int
    repeat: int = 1
    decisions: list[DecisionRow] = field(default_factory=list)

    def metric_values(self) -> dict[str, list[float | None]]:
        """Per metric, one value per session (None where the session has none: no
        activity ended, so no execution time)."""
        return {key: [session_value(s, key) for s in self.sessions] for key in METRICS}

    def adaptation(self) -> dict[str, list[float]]:
        """Per visit (1..repeat): :func:`adaptation` of these sessions."""
        return adaptation(self.sessions, self.repeat)

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
        out["repeat"] = self.repeat
        out["adaptation"] = self.adaptation()
        return out

    def table(self) -> str:
        """The seed's Table 4 for this simulated run, beside the paper's."""
        rows = _rows(self.sessions)
        fails = _failures(self.sessions)
        lines = [
            f"Table 4 (simulated): {len(self.sessions)} sessions of {self.minutes:g} min, "
            f"proactivity {self.proactivity}, seed {self.seed}",
            f"{'Metric type':<15} {'Metric':<38} {'Simulated':<16} Paper",
            "-" * 84,
        ]
        for key, label, kind in _TABLE:
            if kind == "failure":
                value, paper = str(fails[key]), str(PAPER_FAILURES[key])
            else:
                mean, sd = rows[key]
                value = f"{mean:.2f} ({sd:.2f})"
                paper = "{:.2f} ({:.2f})".format(*PAPER[key])
            lines.append(f"{kind_label(kind):<15} {label:<38} {value:<16} {paper}")
        if self.repeat > 1:
            adaptation = self.adaptation()
            lines.append(
                "Kendall tau by visit: "
                + " ".join(f"{v:.2f}" for v in adaptation["kendall_tau_by_session"])
            )
            lines.append(
                "robot-chosen cancels by visit: "
                + " ".join(f"{v:.2f}" for v in adaptation["robot_choice_cancels_by_session"])
            )
        lines.append(f"({self.wall_s:.1f} s wall time)")
        return "\n".join(lines)


def adaptation(sessions: Sequence[SessionMetrics], repeat: int) -> dict[str, list[float]]:
    """Per visit (1..repeat), the mean over participants of Kendall's tau (predicted
    against true ranking, after the visit) and of cancels of robot-chosen activities."""
    taus: list[float] = []
    cancels: list[float] = []
    for visit in range(1, repeat + 1):
        rows = [s for s in sessions if s.visit == visit]
        values = [s.kendall_tau for s in rows if s.kendall_tau is not None]
        taus.append(round(statistics.fmean(values), 3) if values else 0.0)
        cancels.append(round(_mean([float(s.robot_choice_cancels) for s in rows]), 3))
    return {"kendall_tau_by_session": taus, "robot_choice_cancels_by_session": cancels}


def session_value(s: SessionMetrics, key: str) -> float | None:
    """One session's value of a Table 4 metric (None: the session has nothing to average)."""
    if key == "activity_load_time_s":
        return _mean(s.load_times) if s.load_times else None
    if key == "activity_time_s":
        return _mean(s.activity_times) if s.activity_times else None
    if key == "change_time_s":
        return _mean(s.change_times) if s.change_times else None
    counts = {
        "questions_per_session": s.questions,
        "activities_per_session": s.activities,
        "robot_decisions_per_session": s.robot_decisions,
        "user_selections_per_session": s.user_selections,
        "cancels_per_session": s.cancels,
    }
    return float(counts[key])


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
LABELS: dict[str, str] = {key: label for key, label, _kind in _TABLE}


def _mean(values: list[float]) -> float:
    return statistics.fmean(values) if values else 0.0


def _stats(values: list[float]) -> tuple[float, float]:
    if not values:
        return 0.0, 0.0
    return statistics.fmean(values), statistics.pstdev(values) if len(values) > 1 else 0.0


def _rows(sessions: list[SessionMetrics]) -> dict[str, tuple[float, float]]:
    out: dict[str, tuple[float, float]] = {}
    for key in METRICS:
        values = [v for s in sessions if (v := session_value(s, key)) is not None]
        out[key] = _stats(values)
    return out


def _failures(sessions: list[SessionMetrics]) -> dict[str, int]:
    return {
        "activity_not_loaded": sum(s.not_loaded for s in sessions),
        "speech_recognition_errors": sum(s.misrecognized for s in sessions),
        "user_not_answering": sum(s.unanswered for s in sessions),
        "other": sum(s.other_failures for s in sessions),
    }


def kendall_tau(predicted: list[str], truth: list[str]) -> float:
    """Kendall's tau between two rankings of the same activities (scipy.stats.kendalltau
    on each activity's position)."""
    from scipy.stats import kendalltau

    names = [name for name in truth if name in predicted]
    result = kendalltau([predicted.index(n) for n in names], list(range(len(names))))
    value = float(result.statistic)
    return 0.0 if value != value else value  # nan (constant ranking): no agreement


def predicted_ranking(sim: Simulation, user_id: str) -> list[str] | None:
    """The daemon's ranking of the entertainment activities for ``user_id`` now (the
    chooser's expected liking), or None without memory."""
    from memory.errors import ProfileNotFound

    store, chooser = sim.stack.store, sim.stack.chooser
    if store is None or chooser is None:
        return None
    try:
        profile = store.get(user_id)
    except ProfileNotFound:
        return None  # a session too short to meet the participant
    return chooser.ranking(profile, random.Random(0))


def study_settings(
    config: Settings | None = None, config_data: dict[str, Any] | None = None
) -> Settings:
    """The study's settings: the seed's protocol (:data:`PROTOCOL`) for every controller
    setting the configuration does not give itself (``config_data``: the TOML as read)."""
    settings = config or Settings()
    given = (config_data or {}).get("controller") or {}
    updates = {key: value for key, value in PROTOCOL.items() if key not in given}
    return settings.model_copy(
        update={"controller": settings.controller.model_copy(update=updates)}
    )


PROTOCOL: dict[str, Any] = {"session_questions": 4, "question_every": 0}
"""The seed's session protocol: 4-5 general questions after Start, then activities only
(no more questions between them). Applied by the study as configuration, the way an
experimenter configures the robot; a ``--config`` that sets them wins."""


def run_study(
    sessions: int = 30,
    minutes: float = 30.0,
    proactivity: ProactivityLevel = "moderate",
    seed: int = 0,
    settings: Settings | None = None,
    progress: Callable[[int], None] | None = None,
    *,
    repeat: int = 1,
    survey_s: float = SURVEY_S,
    launch_delay_s: tuple[float, float] = LAUNCH_DELAY_S,
    population: Population = "paper",
    record_decisions: bool = False,
) -> StudyResult:
    """Run the study on the virtual clock: ``sessions`` participants, each coming
    ``repeat`` times (all first visits, then all second visits...), each visit
    ``minutes`` long including the ``survey_s`` survey at the end.

    ``settings`` is used as given (see :func:`study_settings` for the seed's protocol).
    ``progress`` is told the number of sessions done after each.
    """
    wall = time.perf_counter()
    rng = random.Random(seed)
    people = participants(sessions, seed, proactivity, population)
    users = {p.id: SimulatedUser(p, random.Random(rng.random())) for p in people}
    results: list[SessionMetrics] = []
    rows: list[DecisionRow] = []
    start = datetime(2026, 11, 23, 9, 0, tzinfo=UTC)
    with Simulation(settings, seed=seed, start=start, launch_delay_s=launch_delay_s) as sim:
        sim.idle_step_s = 10.0  # between participants nobody is there (see sim.harness)
        observer = SessionObserver()
        current: dict[str, Any] = {"session": 0, "participant": "", "visit": 0, "t0": 0.0}

        def on_decision(timed: TimedDecision) -> None:
            observer.on_decision(timed)
            if record_decisions and current["session"]:
                rows.append(
                    DecisionRow(
                        current["session"],
                        current["participant"],
                        current["visit"],
                        round(timed.t - current["t0"], 3),
                        timed.decision,
                    )
                )

        sim.decision_listeners.append(on_decision)
        sim.command_listeners.append(
            lambda cmd, now: observer.on_command(command_handle(sim, cmd), sim.t)
        )
        sim.tick_listeners.append(lambda _record: observer.on_tick(sim.t))
        number = 0
        for visit in range(1, repeat + 1):
            for person in people:
                number += 1
                user = users[person.id]
                user.stats = UserStats()
                began = sim.t
                survey_at = began + minutes * 60.0 - min(survey_s, minutes * 6.0)
                observer = SessionObserver(last_call=survey_at - LAST_CALL_S)
                current.update(session=number, participant=person.id, visit=visit, t0=sim.t)
                unanswered_before = sim.controller.counters.unanswered
                sim.seat(user)
                _run_session(sim, observer, survey_at)
                sim.unseat()
                sim.run_for(1.0)  # the departure is seen and the session closed
                metrics = observer.metrics
                metrics.participant, metrics.visit = person.id, visit
                metrics.misrecognized = user.stats.misrecognized
                metrics.unanswered = sim.controller.counters.unanswered - unanswered_before
                predicted = predicted_ranking(sim, person.id)
                if predicted is not None:
                    metrics.kendall_tau = round(kendall_tau(predicted, person.favourites()), 4)
                observer = SessionObserver()  # the survey and the gap are not measured
                current["session"] = 0
                sim.run_until(began + minutes * 60.0 + GAP_S)
                results.append(metrics)
                if progress is not None:
                    progress(number)
    return StudyResult(
        results, time.perf_counter() - wall, minutes, proactivity, seed, repeat, rows
    )


def _run_session(sim: Simulation, observer: SessionObserver, survey_at: float) -> None:
    """The participant's time with the robot, until their last activity is over
    (``observer.finished``) or the survey begins at ``survey_at`` (the seed's 3 of 30
    minutes; at most a tenth of a shorter session), whichever comes first. At the survey
    the participant gets up whatever runs (an activity under way then ends ``user_left``:
    counted as started, not as a cancel)."""
    if observer.last_call is not None:
        sim.run_until(max(sim.t, observer.last_call))  # no activity can be the last before
    while sim.t < survey_at and not observer.finished:
        sim.run_until(min(sim.t + sim.period, survey_at))
