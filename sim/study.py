"""``dms sim study``: the paper's first experiment with simulated participants.

N participants (default 30) each sit in front of the robot for M minutes (default 30),
one after the other, on one robot with one store, as in the paper's usability study:
the robot asks the protocol's general questions, then activities follow, chosen by the
robot or by the participant according to the participant's proactivity (moderate, as in
the paper, unless ``--proactivity`` says otherwise), until the survey. Each participant
is drawn by :mod:`sim.population` (``--population``); every input (the participants'
habits, the protocol, the robot's launch delay, media lengths) is in
:mod:`sim.calibration` with its source, and none is set from Table 4's metrics: the
study predicts them.

**The session's end, from the paper's protocol.** A session lasts 30 minutes and ends
with a survey of about 3 minutes that the participants filled in "after completing the
activities". So activities go on until the survey is due (27 minutes in): the activity
under way then is the participant's last and is completed, and the participant gets up
for the survey when the robot moves on (a menu or another activity). Between
activities at that moment, they get up at once. The next participant comes when the
survey is over and :data:`GAP_S` has passed.

The metrics are those of the paper's Table 4 (:mod:`sim.table4`), measured on what the
controller decided and the simulated robot did:

- questions per session: general questions asked (``ask`` decisions, reason
  ``general_question``);
- activities per session: activities started for the participant (menus,
  notifications, waiting and sleeping not counted) until their last one;
- activity loading time: from the ``start`` decision until the controller hears from
  the robot that the activity's first command started (its ``started`` feedback): the
  robot's launch delay, the wait for the channel, plus the feedback round, which the
  controller reads at its next update (0 or one tick);
- activity execution time: from ``start`` to ``complete``, ``cancel`` or ``fail``;
- time to change activity: from the end of one activity to the start of the next
  (feedback question, menus and general questions in between);
- robot decisions / user selections: activities started by the robot (predicted
  preferences) / by the participant (menu, by name);
- cancels: activities stopped by the participant (shoulder dialog or by asking for another);
- failures (totals over all sessions): activities that did not load, utterances the
  recognizer got wrong, questions left unanswered, other activity failures.

Beside them, what separates one activity chooser from another (``--chooser``,
:mod:`sim.baselines`): the participant's true liking of the robot's choices, cancels
per robot choice and the time spent in activities the participant likes.
"""

from __future__ import annotations

import dataclasses
import random
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
from typing import Any, Literal

from dms.config import Settings
from dms.kernel.expression import CommandHandle
from dms.kernel.messages import Decision, RobotCommand
from sim.adaptation import (
    by_visit,
    features_ranking,
    kendall_tau,
    population_ranking,
    predicted_ranking,
)
from sim.baselines import ChooserName, install, settings_for
from sim.calibration import DEFAULT, Calibration
from sim.harness import Simulation, TimedDecision
from sim.persona import INITIATIVE_ANSWER, Persona, Preferences, load_persona, shipped_personas
from sim.population import Population, paper_participant
from sim.table4 import (
    LABELS,
    LIKES,
    METRICS,
    OUTCOMES,
    PAPER,
    PAPER_FAILURES,
    TABLE,
    SessionMetrics,
    failures,
    kind_label,
    rows,
    session_value,
)
from sim.user import SimulatedUser, UserStats

__all__ = [
    "LABELS",
    "METRICS",
    "PAPER",
    "PAPER_FAILURES",
    "SessionMetrics",
    "kendall_tau",
    "predicted_ranking",
    "session_value",
]

NOT_COUNTED = frozenset({"menu", "notification", "wait", "sleep", "instructions"})
"""Activities that are not what the participant came for (the paper counts entertainment)."""
USER_CANCEL_REASONS = frozenset({"confirm_cancel", "user_request"})
ACTIVITY_SOURCE = "activity:"
"""The prefix of the arbiter's ``source`` for an activity's commands."""
GAP_S = DEFAULT.number("gap_s")
"""Virtual seconds between two participants."""
SURVEY_S = DEFAULT.number("survey_s")
"""The paper's usability survey at the end of each 30-minute session ("around 3 min")."""
LAUNCH_DELAY_S = DEFAULT.span("launch_delay_s")
"""The simulated Mini's time to launch an activity's process (uniform, seconds):
assumed, see :mod:`sim.calibration`."""
LAST_ACTIVITY_MAX_S = 15 * 60.0
"""At most this long after the survey is due for the last activity to end (an activity
that never ends is cut: the participant gets up)."""

ProactivityLevel = Literal["low", "moderate", "high"]


class SessionObserver:
    """Turns one session's decisions and robot commands into :class:`SessionMetrics`.

    With ``last_call`` (a virtual second: when the survey is due), the activity that
    ends at or after it is the participant's last: nothing after its end is measured,
    and :attr:`finished` turns true when the robot moves on (starts a menu or another
    activity), when the participant gets up for the survey. Without it, every decision
    until the participant leaves is measured. ``liking`` is the participant's true
    liking of an activity, for what the participant got from the session.
    """

    def __init__(
        self, last_call: float | None = None, liking: Callable[[str], float] | None = None
    ) -> None:
        self.metrics = SessionMetrics()
        self.last_call = last_call
        self.liking = liking
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
        self._stop_asked: float | None = None
        """When the participant asked to stop the activity under way (a shoulder touch
        or words), until the next start."""

    @property
    def between_activities(self) -> bool:
        """No activity the participant came for runs now."""
        return not self._started

    def close(self) -> None:
        """The survey is due between two activities: the participant gets up now."""
        self.finished = True

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
        if d.action == "pause" and d.reason == "confirm_cancel":
            self._stop_asked = t  # the shoulder: "continue or stop?"
        elif d.action == "resume" and d.reason == "confirm_cancel":
            self._stop_asked = None  # they went on
        if d.action == "start":
            if self._stop_asked is not None:
                m.stop_times.append(t - self._stop_asked)
                self._stop_asked = None
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
                if self.liking is not None:
                    m.robot_choice_liking.append(self.liking(name))
            elif d.chosen_by == "user":
                m.user_selections += 1
        elif d.action in ("complete", "cancel", "fail"):
            self._first.pop(name, None)
            self._loading.pop(name, None)  # ended before its first command started
            began = self._started.pop(name, None)
            if began is not None:
                m.activity_times.append(t - began)
                self._last_end = t
                if self.liking is not None and self.liking(name) >= LIKES:
                    m.liked_s += t - began
            if d.action == "cancel" and d.reason in USER_CANCEL_REASONS:
                if self._stop_asked is None:
                    self._stop_asked = t  # asked in words: stopped at once
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
    count: int,
    seed: int,
    level: ProactivityLevel,
    population: Population = "paper",
    calibration: Calibration = DEFAULT,
) -> list[Persona]:
    """The study's participants, drawn from their own generator: the same seed gives the
    same people whatever design or chooser runs (``dms sim compare`` pairs sessions on
    them)."""
    rng = random.Random(f"participants/{seed}")
    if population in ("paper", "heldout"):
        heldout = population == "heldout"
        if heldout:
            rng = random.Random(f"heldout/{seed}")
        return [
            paper_participant(index, rng, level, calibration, heldout)
            for index in range(1, count + 1)
        ]
    bases = [load_persona(name) for name in shipped_personas() if name != "demo"]
    return [participant(rng.choice(bases), index, rng, level) for index in range(1, count + 1)]


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
    chooser: str = "dms"
    population: str = "paper"
    events: list[dict[str, Any]] = field(default_factory=list)
    """The sessions' interaction events (``record_events``), one row each."""

    def metric_values(self) -> dict[str, list[float | None]]:
        """Per metric, one value per session (None where the session has none: no
        activity ended, so no execution time)."""
        return {
            key: [session_value(s, key) for s in self.sessions] for key in (*METRICS, *OUTCOMES)
        }

    def of_visit(self, visit: int) -> StudyResult:
        """The sessions of one visit (1..repeat) alone, as a study of one visit."""
        sessions = [s for s in self.sessions if s.visit == visit]
        return dataclasses.replace(self, sessions=sessions, repeat=1, decisions=[])

    def adaptation(self) -> dict[str, list[float]]:
        """Per visit (1..repeat): :func:`adaptation` of these sessions."""
        return adaptation(self.sessions, self.repeat)

    def to_json(self) -> dict[str, Any]:
        """docs/contract.md's keys (per-session means), plus their standard deviations
        and what the participants got (``outcomes``)."""
        table = rows(self.sessions)
        out: dict[str, Any] = {"sessions": len(self.sessions)}
        std: dict[str, float] = {}
        outcomes: dict[str, float] = {}
        for key, (mean, sd) in table.items():
            if key in METRICS:
                out[key] = round(mean, 3)
                std[key] = round(sd, 3)
            else:
                outcomes[key] = round(mean, 3)
        out["failures"] = failures(self.sessions)
        out["wall_s"] = round(self.wall_s, 3)
        out["std"] = std
        out["outcomes"] = outcomes
        out["minutes"] = self.minutes
        out["proactivity"] = self.proactivity
        out["seed"] = self.seed
        out["repeat"] = self.repeat
        out["chooser"] = self.chooser
        out["population"] = self.population
        out["adaptation"] = self.adaptation()
        return out

    def table(self) -> str:
        """The paper's Table 4 for this simulated run, beside the paper's."""
        table = rows(self.sessions)
        fails = failures(self.sessions)
        lines = [
            f"Table 4 (simulated): {len(self.sessions)} sessions of {self.minutes:g} min, "
            f"proactivity {self.proactivity}, seed {self.seed}, chooser {self.chooser}, "
            f"population {self.population}",
            f"{'Metric type':<15} {'Metric':<38} {'Simulated':<16} Paper",
            "-" * 84,
        ]
        for key, label, kind in TABLE:
            if kind == "failure":
                value, paper = str(fails[key]), str(PAPER_FAILURES[key])
            else:
                mean, sd = table[key]
                value = f"{mean:.2f} ({sd:.2f})"
                paper = "{:.2f} ({:.2f})".format(*PAPER[key])
            lines.append(f"{kind_label(kind):<15} {label:<38} {value:<16} {paper}")
        for key in OUTCOMES:
            mean, sd = table[key]
            lines.append(f"{'Outcome':<15} {LABELS[key]:<38} {mean:.2f} ({sd:.2f})")
        if self.repeat > 1:
            by = self.adaptation()
            for key, label in (
                ("kendall_tau_by_session", "Kendall tau by visit"),
                ("tau_features_by_session", "  features only"),
                ("tau_population_by_session", "  population ranking"),
                ("cancels_per_robot_choice_by_session", "cancels per robot choice"),
                ("robot_choice_liking_by_session", "true liking of robot choices"),
            ):
                lines.append(f"{label}: " + " ".join(f"{v:.2f}" for v in by[key]))
        lines.append(f"({self.wall_s:.1f} s wall time)")
        return "\n".join(lines)


def adaptation(sessions: Sequence[SessionMetrics], repeat: int) -> dict[str, list[float]]:
    """Per visit (1..repeat), the means over participants of :func:`sim.adaptation.by_visit`."""
    return by_visit(sessions, repeat)


def study_settings(
    config: Settings | None = None, config_data: dict[str, Any] | None = None
) -> Settings:
    """The study's settings: the paper's protocol (:data:`PROTOCOL`) for every controller
    setting the configuration does not give itself (``config_data``: the TOML as read)."""
    settings = config or Settings()
    given = (config_data or {}).get("controller") or {}
    updates = {key: value for key, value in PROTOCOL.items() if key not in given}
    return settings.model_copy(
        update={"controller": settings.controller.model_copy(update=updates)}
    )


PROTOCOL: dict[str, Any] = {
    "session_questions": int(DEFAULT.number("session_questions")),
    "question_every": 0,
}
"""The paper's session protocol: 4-5 general questions after Start, then activities only
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
    survey_s: float | None = None,
    launch_delay_s: tuple[float, float] | None = None,
    population: Population = "paper",
    record_decisions: bool = False,
    chooser: ChooserName = "dms",
    calibration: Calibration = DEFAULT,
    record_events: bool = False,
) -> StudyResult:
    """Run the study on the virtual clock: ``sessions`` participants, each coming
    ``repeat`` times (all first visits, then all second visits...), each visit
    ``minutes`` long including the ``survey_s`` survey at the end.

    ``settings`` is used as given (see :func:`study_settings` for the paper's protocol).
    ``chooser`` picks the robot's own choices (:mod:`sim.baselines`); ``calibration``
    gives the inputs (:mod:`sim.calibration`). ``progress`` is told the number of
    sessions done after each. ``record_events``: keep the sessions' interaction events
    (:mod:`memory.interactions`, the table ``dms sessions export --events`` prints) in
    :attr:`StudyResult.events`, read from the simulation's store before it is deleted.
    """
    wall = time.perf_counter()
    rng = random.Random(seed)
    people = participants(sessions, seed, proactivity, population, calibration)
    truth = {p.id: p.preferences.model_dump() for p in people}
    users = {p.id: SimulatedUser(p, random.Random(rng.random())) for p in people}
    launch = launch_delay_s if launch_delay_s is not None else calibration.span("launch_delay_s")
    survey_s = calibration.number("survey_s") if survey_s is None else survey_s
    gap_s = calibration.number("gap_s")
    results: list[SessionMetrics] = []
    decision_rows: list[DecisionRow] = []
    start = datetime(2026, 11, 23, 9, 0, tzinfo=UTC)
    settings = settings_for(settings or Settings(), chooser)
    with Simulation(settings, seed=seed, start=start, launch_delay_s=launch) as sim:
        sim.idle_step_s = 10.0  # between participants nobody is there (see sim.harness)
        sim.robot.media_s = calibration.number("media_s")
        install(sim, chooser, truth.get, seed)
        observer = SessionObserver()
        current: dict[str, Any] = {"session": 0, "participant": "", "visit": 0, "t0": 0.0}

        def on_decision(timed: TimedDecision) -> None:
            observer.on_decision(timed)
            if record_decisions and current["session"]:
                decision_rows.append(
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
                survey = min(survey_s, minutes * 6.0)
                survey_at = began + minutes * 60.0 - survey
                observer = SessionObserver(last_call=survey_at, liking=person.liking)
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
                _rank(sim, person, metrics)
                observer = SessionObserver()  # the survey and the gap are not measured
                current["session"] = 0
                sim.run_until(max(began + minutes * 60.0, sim.t + survey) + gap_s)
                results.append(metrics)
                if progress is not None:
                    progress(number)
        events = _events(sim) if record_events else []
    return StudyResult(
        results,
        time.perf_counter() - wall,
        minutes,
        proactivity,
        seed,
        repeat,
        decision_rows,
        chooser,
        population,
        events,
    )


def _events(sim: Simulation) -> list[dict[str, Any]]:
    """The interaction events the simulation's store holds, as ``dms sessions export
    --events`` reads them (the simulated sessions' own table)."""
    store, profiles = sim.stack.store, sim.controller.deps.profiles
    if store is None or profiles is None:
        return []
    profiles.writer.flush()
    return store.interaction_events()


def _rank(sim: Simulation, person: Persona, metrics: SessionMetrics) -> None:
    """Kendall's tau of the daemon's ranking and of the two baselines after a visit."""
    truth = person.favourites()
    predicted = predicted_ranking(sim, person.id)
    if predicted is None:
        return
    metrics.kendall_tau = round(kendall_tau(predicted, truth), 4)
    metrics.tau_population = round(kendall_tau(list(population_ranking()), truth), 4)
    features = features_ranking(sim, person.id)
    if features is not None:
        metrics.tau_features = round(kendall_tau(features, truth), 4)


def _run_session(sim: Simulation, observer: SessionObserver, survey_at: float) -> None:
    """The participant's time with the robot: activities until the survey is due at
    ``survey_at``; the activity under way then is completed (``observer.finished`` turns
    true when the robot moves on), at most :data:`LAST_ACTIVITY_MAX_S` later, when the
    participant gets up whatever runs (an activity under way then ends ``user_left``:
    counted as started, not as a cancel)."""
    sim.run_until(max(sim.t, survey_at))
    if observer.between_activities:
        observer.close()  # nothing under way: they get up for the survey now
    end = survey_at + LAST_ACTIVITY_MAX_S
    while sim.t < end and not observer.finished:
        sim.run_until(min(sim.t + sim.period, end))
