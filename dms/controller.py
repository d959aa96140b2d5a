"""The central controller: the paper's decision loop, one tick at a time.

``Controller.tick(now, monotonic)`` runs steps 1 to 9 of DESIGN.md's decision loop
once and returns a :class:`TickRecord`: the decisions taken, with their reasons, and
the resulting :class:`~dms.kernel.messages.DmsState`. It never reads the clock, never blocks
and never touches Zenoh: the daemon calls it at 2 Hz (and at once on urgent inputs)
and publishes the record; simulations call it on a virtual clock.

Order of work in one tick:

1. Read the inputs (stale and missing ones are left out) and step the motivation.
2. Urgent events: requests, touches, speech and screen choices (answers to a dialog or
   to the running activity first, then requests for an activity by name).
3. If an activity runs: the cancel reasons in the paper's order, (a) the dominant
   motivation changed while no user interacts, (b) the user asked for a change,
   (c) a high-priority agenda item is due, (d) the activity failed or redirected.
4-8. Otherwise choose: the motivation's behavior with no user; with a user, load the
   profile, run a due agenda item, ask a general question or for feedback now and then,
   or choose by the user's proactivity (robot, user, or both with a probability).
"""

from __future__ import annotations

import logging
import random
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from datetime import datetime, timedelta
from typing import Any, Literal, NamedTuple

import numpy as np

from activities import ActivityContext, BehaviorLibrary, reload_rules_and_behaviors
from activities.synonyms import match_activity, requests_activity
from agenda import Agenda, DueItem
from dms.config import ControllerSettings
from dms.dialog import (
    CONFIRM_STOP,
    Dialog,
    DialogKind,
    confirm_dialog,
    feedback_dialog,
    feedback_score,
)
from dms.dialog import SOURCE as DIALOG_SOURCE
from dms.faults import FaultBarrier
from dms.inputs import InputBoard, InputSnapshot
from dms.kernel import keys
from dms.kernel.activity_names import ACTIVITIES, ENTERTAINMENT_ACTIVITIES, ManagerName, manager_of
from dms.kernel.clock import iso
from dms.kernel.expression import ExpressionArbiter
from dms.kernel.messages import (
    ActivityState,
    ChosenBy,
    Decision,
    DecisionAction,
    DmsState,
    Mode,
    ModeWhy,
    MotivationSnapshot,
    MotivationWhy,
    PreferenceWhy,
    Reason,
    Request,
    RuleWhy,
    ScreenChoice,
    Speech,
    Touch,
    UserPerception,
    UserState,
    Why,
)
from dms.kernel.session_metrics import SessionAccount
from dms.profiles import ProfileService
from dms.rules import LiveRules
from dms.scene import Scene
from managers import Manager, ManagerReply, ManagerStatus, make_managers
from memory import ActivityChooser, Profile, Question, QuestionBank
from motivation import (
    MotivationModel,
    MotivationState,
    Percepts,
    Stimuli,
    dominance_holds,
    simulate,
)

log = logging.getLogger(__name__)

_ActivityParts = tuple[str, str, Literal["running", "paused"], str]
"""An ActivityState's fields taken at a tick: name, manager, status, state path."""
_StateParts = tuple[
    str,
    int,
    datetime,
    Mode,
    tuple[str, bool, str, float] | None,
    _ActivityParts | None,
    _ActivityParts | None,
    Mapping[str, Any],
    bool,
]
""":func:`_dms_state`'s arguments but the motivation (robot, tick, now, mode, user,
activity, suspended, inputs, offline)."""

NO_FEEDBACK_FOR = frozenset({"menu", "notification", "sleep", "wait", "instructions"})
"""Activities after which the robot does not ask how much the user liked them."""

MODE_BY_PROACTIVITY: dict[str, Mode] = {
    "high": "user_choice",
    "low": "autonomous",
    "moderate": "hybrid",
    "unknown": "hybrid",
}
RULE_MODES: dict[str, float] = {"autonomous": 0.0, "user_choice": 1.0, "hybrid": 0.5}
"""A ``ChooseMode`` activation and the probability that the user takes the initiative."""


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


class _TickState:
    """What DmsState is made of, taken at one tick (the controller moves on after it);
    the models are made on first read, once.

    Every tick makes one and most are never read (a simulation reads none): plain values
    in one object, no closures (issue 14). ``parts`` are :func:`_dms_state`'s arguments
    but the motivation, which is ``_motivation_snapshot(model, motivation_state)``.
    """

    __slots__ = ("_model", "_motivation", "_motivation_state", "_parts", "_state")

    def __init__(
        self, parts: _StateParts, model: MotivationModel, motivation_state: MotivationState | None
    ) -> None:
        self._parts = parts
        self._model = model
        self._motivation_state = motivation_state
        self._state: DmsState | None = None
        self._motivation: MotivationSnapshot | None = None

    def motivation(self) -> MotivationSnapshot:
        if self._motivation is None:
            self._motivation = _motivation_snapshot(self._model, self._motivation_state)
        return self._motivation

    def state(self) -> DmsState:
        if self._state is None:
            self._state = _dms_state(*self._parts, self.motivation())
        return self._state


class TickRecord(NamedTuple):
    """What one tick decided and the state it left: logged, published, asserted.

    ``state`` is built on first read from what the tick left (taken at the tick): a
    simulation that never reads it does not pay for the model (issue 14). A named
    tuple, not a frozen dataclass: as immutable, at half the cost of making one (one
    a tick).
    """

    tick: int
    time: datetime
    urgent: bool
    decisions: tuple[Decision, ...]
    taken: _TickState
    """What the state is made of, taken at the tick."""
    activity: str | None = None
    """``state.activity.name``: the current activity (running or paused), if any."""
    motivation_state: MotivationState | None = None
    """The motivation model's own state after the tick, of which ``motivation`` is the
    snapshot: a reader that wants a few numbers every tick (the long-term tracker) takes
    them from it with the model, without the snapshot's model (issue 14)."""

    @property
    def state(self) -> DmsState:
        return self.taken.state()

    @property
    def motivation(self) -> MotivationSnapshot:
        """``state.motivation`` alone (cheaper than the whole state)."""
        return self.taken.motivation()


@dataclass
class Counters:
    """Running totals for metrics and studies."""

    ticks: int = 0
    decisions: int = 0
    activity_failures: int = 0
    not_loaded: int = 0
    unanswered: int = 0
    misheard: int = 0
    """Utterances under ``min_speech_confidence``: speech recognition errors."""
    by_reason: dict[str, int] = field(default_factory=dict)


@dataclass
class ControllerDeps:
    """Everything the controller works with; the daemon and the simulator build it."""

    library: BehaviorLibrary
    expression: ExpressionArbiter
    motivation: MotivationModel
    profiles: ProfileService | None = None
    agenda: Agenda | None = None
    rules: LiveRules | None = None
    chooser: ActivityChooser | None = None
    questions: QuestionBank | None = None
    report_error: Callable[[str, str], None] = lambda key, error: None
    robot_state: Callable[[], Mapping[str, Any]] = dict
    scene: Scene | None = None
    """The frames behaviors aim at (the user's face, objects, the body); None: no gaze."""


@dataclass(frozen=True, slots=True)
class _Asked:
    """A start or cancel asked for, served at the next decision point of this tick."""

    target: str
    """The activity to start; empty for a cancel."""
    chosen_by: ChosenBy | None
    detail: str
    own: bool
    """The user's own act (voice, screen, a request ``by`` the user), not an app's or a
    caregiver's: only the user's own acts tell their proactivity and preferences."""


@dataclass
class _Session:
    user_id: str
    session_id: str | None
    """The key ProfileService made for it (the database's id comes later, off the tick)."""
    started: datetime
    mode: Mode
    p_user: float
    mode_detail: str | None
    questions_left: int
    activities_done: int = 0
    asked: set[str] = field(default_factory=set)
    last_activity: str | None = None
    robot_turn: bool = False
    """The user left the choice to the robot (declined the menu): the next pick is the
    robot's."""
    account: SessionAccount | None = None
    """The session's Table 4 metrics, stored with it when it ends."""
    resume: tuple[str, ChosenBy, float] | None = None
    """An activity a session end cut (here or at another robot), to start again first:
    (name, who chose it, seconds since), with ``resume_cut_within_s``."""


class Controller:
    """The decision loop over managers, activities, motivation, memory and agenda."""

    def __init__(
        self,
        deps: ControllerDeps,
        inputs: InputBoard,
        settings: ControllerSettings | None = None,
        robot_id: str = "mini",
        rng: random.Random | None = None,
        timezone_hour: Callable[[datetime], int] = lambda t: t.hour,
    ) -> None:
        self.deps = deps
        self.inputs = inputs
        self.settings = settings or ControllerSettings()
        self.robot_id = robot_id
        self.rng = rng or random.Random()
        self._hour = timezone_hour
        self.managers: dict[ManagerName, Manager] = make_managers(deps.library)
        self.counters = Counters()
        self._tick = 0
        self._decisions: list[Decision] = []
        self._now: datetime | None = None
        self._last_step: datetime | None = None
        self._motivation: MotivationState | None = None
        self._percepts: Percepts | None = None
        self._seen: tuple[object, ...] = ()
        """The fields of ``_percepts``, as a tuple (Percepts compare the same way)."""
        self._stimuli: Stimuli | None = None
        self.current: Running | None = None
        self.suspended: Running | None = None
        self.dialog: Dialog | None = None
        self._question: Question | None = None
        self._session: _Session | None = None
        self._snapshot: InputSnapshot | None = None
        self._user: UserPerception | None = None
        self._requests: list[_Asked] = []
        self._touches: list[tuple[str, str]] = []
        self._taken: _TickState | None = None
        self._robot_blocked = False
        self._cleaning: set[ManagerName] = set()
        """Managers whose cancelled activities still run their cleanup states."""
        self._unknown_since: datetime | None = None
        self._probe_at: datetime | None = None
        self._probe_wait_s = 0.0
        self._barrier = FaultBarrier(
            deps.report_error, clock=lambda: self._now.timestamp() if self._now else 0.0
        )

    # ------------------------------------------------------------------ the tick

    def tick(self, now: datetime, monotonic: float, urgent: bool = False) -> TickRecord:
        """Run the decision loop once at ``now``; see the module docstring."""
        self._now = now
        self._tick += 1
        self.counters.ticks += 1
        self._decisions = []
        snapshot = self._snapshot = self.inputs.take(monotonic)
        user = snapshot.values.get(keys.PERCEPTION_USER)
        self._user = user if isinstance(user, UserPerception) else None
        self._touches = []
        self._handle_events(snapshot, now)
        # Each step is guarded by a plain ``try`` (free in Python 3.11 while nothing
        # raises) instead of a ``with`` of the fault barrier: nine steps a tick were a
        # tenth of its cost. A fault is contained as the barrier does it (_contain).
        try:
            self._step_motivation(snapshot, now)
        except Exception as error:
            self._contain("motivation", self._user, error)
        try:
            if self.deps.scene is not None:
                self.deps.scene.update(snapshot.values, snapshot.fresh, now)
            self.deps.expression.update(now)
            self._robot_blocked = self._robot_unreachable(now)
        except Exception as error:
            self._contain("robot", None, error)
        if self.deps.profiles is not None:
            try:
                self.deps.profiles.retry(now)
            except Exception as error:
                self._contain("memory", None, error)
        try:
            self._track_user(now)
        except Exception as error:
            self._contain("user", self._user, error)
        dialog = self.dialog
        if dialog is not None:
            try:
                self._advance_dialog(now)
            except Exception as error:
                self._contain("dialog", dialog.kind.value, error)
                self._drop_dialog(now)
        if self._cleaning:
            try:
                self._wind_down(now)
            except Exception as error:
                self._contain("cleanup", None, error)
        if self.dialog is None:
            running = self.current
            if running is not None:
                try:
                    self._tick_activities(now)
                except Exception as error:
                    self._contain("activity", running.name, error)
                    self._abandon_current(now, "activity")
            running = self.current
            if running is not None:
                try:
                    self._check_cancel_reasons(now)
                except Exception as error:
                    self._contain("cancel", running.name, error)
                    self._abandon_current(now, "cancel")
            if self.current is None and self.dialog is None:
                try:
                    self._choose(now)
                except Exception as error:
                    self._contain("choose", self._ready_user(), error)
        session = self._session
        if session is not None and session.account is not None:
            try:  # after the sends of this tick: see SessionAccount.on_tick
                session.account.on_tick(now, self.deps.expression.pending)
            except Exception as error:
                self._contain("metrics", None, error)
        taken = self._taken = self._state_of(now)
        self.counters.decisions += len(self._decisions)
        current = self.current.name if self.current is not None else None
        return TickRecord(
            self._tick,
            now,
            urgent,
            tuple(self._decisions),
            taken,
            current,
            self._motivation,
        )

    def _contain(self, step: str, subject: object, error: Exception) -> None:
        """Contain ``error``, raised by the tick's ``step`` working on ``subject``, exactly
        as a ``with`` of :meth:`FaultBarrier.step` does: logged, reported, the loop goes on."""
        with self._barrier.step(step, subject):
            raise error

    def shutdown(self, now: datetime) -> TickRecord:
        """Stop what runs (SIGINT/SIGTERM): cancel the activity and any suspended one."""
        self._now = now
        self._decisions = []
        if self.dialog is not None:
            self._end_dialog(now)
        for running in (self.current, self.suspended):
            if running is not None:
                with self._barrier.step("shutdown", running.name):
                    self._cancel(running, "shutdown", now, cleanup=False)
        self.current = self.suspended = None
        for manager in self.managers.values():
            with self._barrier.step("shutdown", manager.name):
                manager.stop_winding_down(now)
        if self._session is not None:
            with self._barrier.step("shutdown", self._session.user_id):
                self._end_session(now)
        taken = self._taken = self._state_of(now)
        return TickRecord(self._tick, now, False, tuple(self._decisions), taken)

    # ------------------------------------------------------------------ step 1

    def _step_motivation(self, snapshot: InputSnapshot, now: datetime) -> None:
        model = self.deps.motivation
        if self._motivation is None:
            self._motivation = model.initial_state(now)
            self._last_step = now
        dt = (now - self._last_step).total_seconds() if self._last_step else 0.0
        if dt <= 0:
            return
        user, values = self._user, snapshot.values
        seen = (  # Percepts' fields: the object is made only when they change
            (user.present if user else False) if keys.PERCEPTION_USER in values else None,
            user.engagement if user else None,
            snapshot.env_params if keys.PARAMS_ENV in values else None,
            tuple(self._touches),
        )
        stimuli = self._stimuli
        if seen != self._seen or stimuli is None:
            self._percepts = Percepts(*seen)
            # the room rarely changes between ticks
            stimuli = self._stimuli = model.stimuli(self._percepts)
            self._seen = seen
        running = self.current.name if self.current and not self.current.paused else None
        self._motivation = model.step(self._motivation, dt, stimuli, running, now)
        self._last_step = now

    def next_motivated_change(self, now: datetime, horizon_s: float) -> float | None:
        """Seconds from ``now`` to the tick at which, with the inputs as they are, the
        motivated behavior would change; None if not within ``horizon_s``.

        For simulations that skip the ticks of an empty room: they may jump this far and
        lose nothing, since the motivation is exact over any step.
        """
        state, percepts = self._motivation, self._percepts
        if state is None or percepts is None:
            return None
        model = self.deps.motivation
        stimuli = model.stimuli(Percepts(percepts.user_present, percepts.engagement, percepts.env))
        running = self.current.name if self.current and not self.current.paused else None
        if dominance_holds(model, state, stimuli, running, horizon_s):
            return None  # no drive is near a threshold: no run needed to know
        period = self.settings.tick_period_s
        run = simulate(
            model,
            state,
            now,
            horizon_s,
            stimuli,
            running=running,
            tick_s=period,
            only_dominant=True,
        )
        expected = model.behavior(state)
        behaviors = [*model.table.behaviors, model.config.idle_behavior]
        # the dominant drive's index at each tick, -1 for none: the idle behavior, last
        same = np.array([behavior == expected for behavior in behaviors])[run.dominant]
        if same.all():
            return None
        return (int(np.argmin(same)) + 1) * period  # the first tick of another behavior

    # ------------------------------------------------------------------ step 2: events

    def _handle_events(self, snapshot: InputSnapshot, now: datetime) -> None:
        for event in snapshot.events:
            with self._barrier.step(f"event/{event.key}", event.message):
                self._handle_event(event.message, now)

    def _handle_event(self, message: object, now: datetime) -> None:
        """One urgent input: a request, a touch, an utterance or a screen choice."""
        if isinstance(message, Request):
            self._on_request(message, now)
        elif isinstance(message, Touch):
            self._touches.append((message.part, message.kind))
            self._on_touch(message, now)
        elif isinstance(message, Speech):
            if message.confidence < self.settings.min_speech_confidence:
                log.info("not understood (confidence %.2f): %r", message.confidence, message.text)
                self.counters.misheard += 1
                return
            self._on_answer(message.text, "voice", message, now)
        elif isinstance(message, ScreenChoice):
            self._on_answer(message.choice, "screen", message, now)

    def _on_request(self, request: Request, now: datetime) -> None:
        """A request from another program: served in this tick, or answered with why not."""
        by = request.by or "request"
        own = self._is_the_user(request.by)
        running = self.current
        if request.action == "reload_rules":
            self.reload_rules()
        elif request.action == "start" and request.activity is not None:
            self._close_question(now)
            self._requests.append(_Asked(request.activity, "user", f"requested by {by}", own))
            if own:
                self._note_initiative(True, now)
        elif request.action == "start":
            self._refuse(request, "start needs an activity")
        elif request.action == "cancel" and self._withdraw_pending(request.activity):
            pass  # asked for earlier in this tick and not started yet: it never starts
        elif request.action == "cancel" and running is not None:
            if request.activity in (None, running.name):
                self._close_question(now)
                self._requests.append(_Asked("", "user", f"cancel requested by {by}", own))
            else:
                self._refuse(request, f"{request.activity} does not run ({running.name} does)")
        elif request.action == "pause" and running is not None and not running.paused:
            self._pause(running, "user_request", now, f"requested by {by}")
        elif request.action == "resume" and running is not None and running.paused:
            if self.dialog is not None and self.dialog.kind is DialogKind.CONFIRM_CANCEL:
                self.dialog.offer("continue", "request")  # the answer to "continue or stop?"
                self._advance_dialog(now)
            else:
                self._resume(running, "user_request", now, f"requested by {by}")
        elif running is None:
            self._refuse(request, f"nothing to {request.action}: no activity runs")
        else:
            state = "paused" if running.paused else "running"
            self._refuse(request, f"nothing to {request.action}: {running.name} is {state}")

    def _withdraw_pending(self, activity: str | None) -> bool:
        """Drop a start of ``activity`` still waiting in this tick; True if there was one."""
        for asked in self._requests:
            if asked.target and asked.target == activity:
                self._requests.remove(asked)
                return True
        return False

    def _is_the_user(self, by: str | None) -> bool:
        """A request ``by`` the user in front of the robot (``"user"`` or their id)."""
        session = self._session
        return by is not None and session is not None and by in ("user", session.user_id)

    def _refuse(self, request: Request, why: str) -> None:
        """A request that cannot be served: said on ``dms/errors``, never dropped silently."""
        who = request.by or "request"
        self.deps.report_error(keys.REQUEST, f"{request.action} by {who}: {why}")

    def _close_question(self, now: datetime) -> None:
        """A request arrived while a general or feedback question is open: the request
        wins, the question closes at once (not counted as unanswered)."""
        dialog = self.dialog
        if dialog is not None and dialog.kind in (DialogKind.GENERAL_QUESTION, DialogKind.FEEDBACK):
            self._end_dialog(now)

    def _end_dialog(self, now: datetime) -> None:
        """Close the open dialog without its answer and silence what it was saying."""
        self.dialog = None
        self._question = None
        self.deps.expression.interrupt_source(DIALOG_SOURCE, now)

    def _on_touch(self, touch: Touch, now: datetime) -> None:
        running = self.current
        if (
            touch.part == "right_shoulder"
            and running is not None
            and self.dialog is None
            and running.chosen_by != "motivation"
            and not running.paused
            and running.name != "notification"
        ):
            self._pause(running, "confirm_cancel", now, "right shoulder touched")
            self._open_dialog(
                confirm_dialog(running.name, now, self.settings.confirm_timeout_s), now
            )
            return
        if running is not None:
            self.managers[running.manager].deliver(touch)

    def _on_answer(
        self, text: str, channel: str, event: Speech | ScreenChoice, now: datetime
    ) -> None:
        wanted = match_activity(text)
        if self.dialog is not None:
            asks_instead = (
                wanted is not None
                and self.dialog.kind in (DialogKind.GENERAL_QUESTION, DialogKind.FEEDBACK)
                and (bool(self.dialog.choices) or requests_activity(text))
            )
            if not asks_instead:
                if self.dialog.offer(text, channel):
                    self._advance_dialog(now)
                return
            self._close_question(now)
        running = self.current
        if running is not None and self.managers[running.manager].deliver(event):
            return
        if (
            wanted is not None
            and wanted in ACTIVITIES
            and (running is None or wanted != running.name)
        ):
            detail = f"asked by {channel}: {text[:60]!r}"
            self._requests.append(_Asked(wanted, "user", detail, own=True))
            self._note_initiative(True, now)

    # ------------------------------------------------------------------ dialogs

    def _open_dialog(self, dialog: Dialog, now: datetime) -> None:
        self.dialog = dialog
        dialog.ask(self.deps.expression, now, self._style())
        activity = dialog.context.get("activity")
        self._decide("ask", activity, dialog.kind.value, None, dialog.question, now)

    def _advance_dialog(self, now: datetime) -> None:
        dialog = self.dialog
        if dialog is None or (dialog.answer is None and not dialog.expired(now)):
            return
        self.dialog = None
        self.deps.expression.interrupt_source(DIALOG_SOURCE, now)
        answered = dialog.answer is not None
        self._note_interaction(dialog.channel or self._style(), answered, now)
        if dialog.kind is DialogKind.CONFIRM_CANCEL:
            self._close_confirm(dialog, now)
        elif dialog.kind is DialogKind.FEEDBACK and dialog.answer is not None:
            score = feedback_score(dialog.answer)
            if score is not None and self._session is not None:
                self._profiles_call(
                    "record_feedback", self._session.user_id, dialog.context["activity"], score, now
                )
        elif dialog.kind is DialogKind.GENERAL_QUESTION:
            question = self._question
            self._question = None
            if question is not None and dialog.answer is not None and self._session:
                self._profiles_call(
                    "record_answer", self._session.user_id, question.id, dialog.answer, now
                )
        if not answered:
            self.counters.unanswered += 1

    def _close_confirm(self, dialog: Dialog, now: datetime) -> None:
        running = self.current
        if running is None:
            return
        if dialog.answer is not None and dialog.answer in CONFIRM_STOP:
            self._note_initiative(True, now)  # the user stopped it: their own initiative
            self._cancel(running, "confirm_cancel", now, f"the user said {dialog.answer!r}")
            self._finish_user_activity(running, "cancelled", now, ask_feedback=False)
            self.current = None
        else:
            why = f"the user said {dialog.answer!r}" if dialog.answer else "no answer"
            self._resume(running, "confirm_cancel", now, why)

    def _drop_dialog(self, now: datetime) -> None:
        """After a fault in the dialog step: close the dialog, silence it, go on."""
        self.dialog = None
        with self._barrier.step("dialog/close"):
            self._end_dialog(now)
        running = self.current
        if running is not None and running.paused and self.suspended is not running:
            with self._barrier.step("dialog/resume", running.name):
                self._resume(running, "confirm_cancel", now, "the dialog failed")

    def _abandon_current(self, now: datetime, step: str) -> None:
        """After a fault while running or checking the activity: stop it as failed, so
        that what the state says and what the robot does agree again."""
        running = self.current
        if running is None:
            return
        self.current = None
        with self._barrier.step(f"{step}/stop", running.name):
            self.managers[running.manager].cancel(now)
        with self._barrier.step(f"{step}/stop", running.name):
            self.deps.expression.interrupt_source(f"activity:{running.name}", now)
        self.counters.activity_failures += 1
        self._decide(
            "fail", running.name, "activity_error", running.chosen_by, f"{step} step failed", now
        )
        with self._barrier.step(f"{step}/record", running.name):
            self._finish_user_activity(running, "failed", now, ask_feedback=False)
        if self.suspended is not None and self.dialog is None:
            suspended, self.suspended = self.suspended, None
            self.current = suspended
            with self._barrier.step(f"{step}/resume", suspended.name):
                self._resume(suspended, "activity_error", now, f"after the {running.name}")

    @property
    def faults(self) -> int:
        """Exceptions the fault barrier contained since the start."""
        return len(self._barrier.faults)

    # ------------------------------------------------------------------ user presence

    def _ready_user(self) -> str | None:
        user = self._user
        if user is not None and user.present and user.ready and user.user_id:
            return user.user_id
        return None

    def _perception_unknown(self) -> bool:
        """``perception/user`` is stale or missing: who is there is unknown (not "nobody")."""
        return self._snapshot is not None and keys.PERCEPTION_USER not in self._snapshot.values

    def _track_user(self, now: datetime) -> None:
        session, user = self._session, self._user
        if (
            session is not None
            and user is not None
            and user.present
            and user.user_id in (None, session.user_id)
        ):
            self._unknown_since = None  # still there (most ticks): what follows would agree
            return
        ready = self._ready_user()
        reason: Reason = "user_left"
        if session is not None and self._perception_unknown():
            # An absent module is not considered (seed 001): the session and its activity
            # go on, nothing new starts, and only a long silence ends the session.
            since = self._unknown_since = self._unknown_since or now
            if (now - since).total_seconds() < self.settings.perception_grace_s:
                return
            reason = "input_missing"
        else:
            self._unknown_since = None
        gone = session is not None and (
            reason == "input_missing" or self._user_gone(session.user_id)
        )
        if session is not None and gone:
            self._unknown_since = None
            why = (
                f"no perception of {session.user_id} for {self.settings.perception_grace_s:g} s"
                if reason == "input_missing"
                else f"{session.user_id} is gone"
            )
            # leaving (or going unseen) says nothing of what the user thought of the
            # activity: the session's end cut it (only the user's own stop counts), and
            # a robot that sees her again may resume it (resume_cut_within_s)
            outcome = "cut"
            for running in (self.current, self.suspended):
                if running is not None and running.user_id == session.user_id:
                    self._cancel(running, reason, now, why)
                    self._finish_user_activity(running, outcome, now, ask_feedback=False)
                    if running is self.current:
                        self.current = None
                    else:
                        self.suspended = None
            if self.dialog is not None:
                self._end_dialog(now)
            self._end_session(now)
            session = None
        if session is None and ready is not None:
            self._begin_session(ready, now)

    def _user_gone(self, user_id: str) -> bool:
        user = self._user
        if user is None:
            return True
        return not user.present or (user.user_id is not None and user.user_id != user_id)

    def _begin_session(self, user_id: str, now: datetime) -> None:
        profile = self._load_profile(user_id, now)
        session_id = self._profiles_call("start_session", user_id, now)
        if self.deps.agenda is not None:
            self._agenda_call("user_perceived", user_id, now)
        # the session first, so that ChooseMode sees params.user (the profile and its id)
        self._session = session = _Session(
            user_id=user_id,
            session_id=session_id if isinstance(session_id, str) else None,
            started=now,
            mode="hybrid",
            p_user=0.5,
            mode_detail=None,
            questions_left=self.settings.session_questions,
            account=SessionAccount(
                now, misheard=self.counters.misheard, unanswered=self.counters.unanswered
            ),
        )
        session.mode, session.p_user, session.mode_detail = self._choose_mode(profile)
        session.resume = self._cut_to_resume(user_id, now)
        log.info("user %s is ready (mode %s)", user_id, session.mode)

    def _cut_to_resume(self, user_id: str, now: datetime) -> tuple[str, ChosenBy, float] | None:
        """The user's last run, if a session end cut it within ``resume_cut_within_s``
        (read off the tick, waited for like the profile; not in time: nothing)."""
        window = self.settings.resume_cut_within_s
        if window <= 0 or self.deps.profiles is None:
            return None
        last = self.deps.profiles.ask("last_run", user_id)
        if not isinstance(last, dict) or last.get("outcome") != "cut":
            return None
        name, ended = last.get("activity"), last.get("ended")
        if name not in ACTIVITIES or not isinstance(ended, datetime):
            return None
        age = (now - ended).total_seconds()
        if not 0 <= age <= window:
            return None
        chosen_by = last.get("chosen_by")
        return str(name), chosen_by if chosen_by in ("robot", "user") else "robot", age

    def _end_session(self, now: datetime) -> None:
        session = self._session
        self._session = None
        if session is not None and session.session_id is not None:
            metrics = None
            if session.account is not None:
                counters = self.counters
                metrics = session.account.result(
                    now, misheard=counters.misheard, unanswered=counters.unanswered
                )
            self._profiles_call("end_session", session.session_id, now, metrics=metrics)
        if session is not None and self.deps.chooser is not None:
            self.deps.chooser.session_ended(now)  # retrains in the background, if due

    def _load_profile(self, user_id: str, now: datetime) -> Profile | None:
        """Read off the tick: a healthy database answers within the tick (LOAD_WAIT_S);
        else the session begins at once on the cached (or an empty) profile, and the
        profile is used as soon as it lands (the user is not kept waiting)."""
        if self.deps.profiles is None:
            return None
        return self.deps.profiles.load(user_id, now)

    def _profile(self) -> Profile | None:
        if self.deps.profiles is None or self._session is None:
            return None
        return self.deps.profiles.cached(self._session.user_id)

    def _style(self) -> str:
        profile = self._profile()
        return str(getattr(profile, "interaction_style", None) or "voice")

    def _choose_mode(self, profile: Profile | None) -> tuple[Mode, float, str | None]:
        result = self._rule("ChooseMode")
        if result is not None and result.activate and result.activate[0] in RULE_MODES:
            chosen = result.activate[0]
            mode: Mode = chosen
            return mode, RULE_MODES[chosen], f"rule ChooseMode -> {chosen}"
        proactivity = str(getattr(profile, "proactivity", None) or "unknown")
        p_user = self.settings.user_initiative.get(proactivity, 0.5)  # type: ignore[call-overload]
        return MODE_BY_PROACTIVITY.get(proactivity, "hybrid"), p_user, None

    # ------------------------------------------------------------------ activities

    def _context(self, name: str) -> ActivityContext:
        return ActivityContext(
            expression=self.deps.expression,
            source=f"activity:{name}",
            params=self.params,
            rules=self.deps.rules,
            rng=self.rng,
            set_user_param=self._set_user_param,
            frames=self.deps.scene.frames if self.deps.scene is not None else None,
            joints=self.deps.scene.joints if self.deps.scene is not None else {},
        )

    def _set_user_param(self, name: str, value: Any) -> None:
        if self._session is not None and self._now is not None:
            self._profiles_call("update", self._session.user_id, self._now, **{name: value})

    def params(self) -> Mapping[str, Mapping[str, Any]]:
        """``params.user``, ``params.robot`` and ``params.env`` for rules and behaviors."""
        profile = self._profile()
        user: dict[str, Any] = dict(profile.params()) if profile is not None else {}
        if self._session is not None:
            user.setdefault("id", self._session.user_id)
        snapshot = self._snapshot
        robot = {**self.deps.robot_state(), **(snapshot.robot_params if snapshot else {})}
        if self.current is not None:  # what the robot is doing, unless params/robot says
            robot.setdefault("currenttask", self.current.name)
        env: dict[str, Any] = dict(snapshot.env_params) if snapshot else {}
        if self._now is not None:
            env["time"] = self._hour(self._now)
        return {"user": user, "robot": robot, "env": env}

    def _rule(self, component: str) -> Any:
        rules = self.deps.rules
        if rules is None:
            return None
        try:
            return rules.evaluate(component, self.params())
        except Exception as error:  # a designer's rule must never stop the robot
            log.exception("rule %s failed", component)
            self.deps.report_error("rules", f"{component}: {error}")
            return None

    def reload_rules(self) -> None:
        """Reload the rules files and the behaviors; each keeps its old version if the new
        one does not verify. Activities started afterwards use the new behaviors."""
        for key, problem in reload_rules_and_behaviors(self.deps.library, self.deps.rules):
            self.deps.report_error(key, problem)

    def _start(
        self,
        name: str,
        reason: Reason,
        chosen_by: ChosenBy | None,
        now: datetime,
        detail: str | None = None,
        args: Mapping[str, Any] | None = None,
        agenda_item: DueItem | None = None,
        why: Why | None = None,
    ) -> bool:
        if self._robot_blocked:
            if chosen_by == "user" or reason == "user_request":  # said, never dropped silently
                self._decide("fail", name, "activity_error", chosen_by, "the robot is offline", now)
            return False
        manager = manager_of(name)
        reply = self.managers[manager].start(name, self._context(name), now, args)
        if reply.status is not ManagerStatus.RUNNING:
            self.counters.not_loaded += 1
            self._decide("fail", name, "activity_error", chosen_by, reply.detail, now)
            return False
        user_id = self._session.user_id if self._session else None
        self.current = Running(
            name, manager, chosen_by, reason, now, user_id, agenda_item=agenda_item
        )
        self._decide("start", name, reason, chosen_by, detail, now, why)
        return True

    def _pause(self, running: Running, reason: Reason, now: datetime, detail: str | None) -> None:
        self.managers[running.manager].pause(now)
        running.paused = True
        self._decide("pause", running.name, reason, running.chosen_by, detail, now)

    def _resume(self, running: Running, reason: Reason, now: datetime, detail: str | None) -> None:
        self.managers[running.manager].resume(now)
        running.paused = False
        self._decide("resume", running.name, reason, running.chosen_by, detail, now)

    def _cancel(
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
            self._cleaning.add(running.manager)
        self._decide("cancel", running.name, reason, running.chosen_by, detail, now)
        return reply

    def _wind_down(self, now: datetime) -> None:
        """Tick the cleanup states of cancelled activities (also while a dialog is open)."""
        for name in list(self._cleaning):
            manager = self.managers[name]
            manager.wind_down(now)
            if not manager.winding_down:
                self._cleaning.discard(name)

    def _tick_activities(self, now: datetime) -> None:
        running = self.current
        if running is None:
            return
        reply = self.managers[running.manager].tick(now)
        if reply.status in (ManagerStatus.RUNNING, ManagerStatus.PAUSED, ManagerStatus.IDLE):
            if reply.status is ManagerStatus.IDLE:
                self.current = None  # the manager lost it: start afresh
            return
        self.current = None
        if reply.status is ManagerStatus.FAILED:
            self.counters.activity_failures += 1
            self._decide(
                "fail", running.name, "activity_error", running.chosen_by, reply.detail, now
            )
            self._finish_user_activity(running, "failed", now, ask_feedback=False)
        elif reply.status is ManagerStatus.COMPLETED:
            self._decide(
                "complete", running.name, "completed", running.chosen_by, reply.detail, now
            )
            if running.name == "menu" and not reply.redirect and self._session is not None:
                self._note_initiative(False, now)  # offered the choice, left it to the robot
                self._session.robot_turn = True
            self._finish_user_activity(running, "completed", now, ask_feedback=not reply.redirect)
            if reply.redirect:
                self._follow_redirect(running, reply.redirect, now)
        elif reply.status is ManagerStatus.CANCELLED:
            self._finish_user_activity(running, "cancelled", now, ask_feedback=False)
        if self.current is None and self.suspended is not None:
            suspended, self.suspended = self.suspended, None
            self.current = suspended
            self._resume(suspended, "agenda", now, f"after the {running.name}")

    def _follow_redirect(self, running: Running, target: str, now: datetime) -> None:
        if target not in ACTIVITIES:
            self._decide(
                "fail",
                running.name,
                "activity_error",
                running.chosen_by,
                f"redirect to unknown {target!r}",
                now,
            )
            return
        if running.name == "menu":
            self._note_initiative(True, now)
            self._start(target, "user_choice", "user", now, "chosen from the menu")
        else:
            self._start(
                target, "activity_redirect", running.chosen_by, now, f"asked for by {running.name}"
            )

    def _finish_user_activity(
        self, running: Running, outcome: str, now: datetime, ask_feedback: bool
    ) -> None:
        session = self._session
        if session is None or running.user_id != session.user_id or running.name in ("menu",):
            return
        self._profiles_call(
            "record_activity",
            session.user_id,
            running.name,
            running.started,
            now,
            outcome,
            running.chosen_by or "robot",
            outcome == "cancelled",
            session.session_id,
        )
        if running.name in NO_FEEDBACK_FOR:
            return
        session.activities_done += 1
        session.last_activity = running.name
        if ask_feedback and self.rng.random() < self.settings.feedback_probability:
            self._open_dialog(
                feedback_dialog(running.name, now, self.settings.question_timeout_s), now
            )

    # ------------------------------------------------------------------ step 2: cancel reasons

    def _check_cancel_reasons(self, now: datetime) -> None:
        running = self.current
        assert running is not None
        ready = self._ready_user()
        # (a) no user interacts and the dominant motivation changed
        if running.chosen_by == "motivation":
            if ready is not None:
                self._cancel(running, "user_arrived", now, f"{ready} is ready to interact")
                self.current = None
                return
            wanted = self._motivated_behavior()
            if wanted != running.name and self._interruption_allowed(running):
                self._cancel(
                    running,
                    "motivation_changed",
                    now,
                    f"now {self._dominant() or 'none'} dominates",
                )
                self.current = None
                return
        # (b) the user asked to change
        if self._requests:
            asked = self._requests.pop(0)
            target, chosen_by, detail = asked.target, asked.chosen_by, asked.detail
            if target != running.name:
                self._cancel(running, "user_request", now, detail)
                # an app's or a caregiver's stop says nothing of what the user likes
                outcome = "cancelled" if asked.own else "stopped"
                self._finish_user_activity(running, outcome, now, ask_feedback=False)
                self.current = None
                if self.suspended is not None:
                    self._cancel(self.suspended, "user_request", now, detail)
                    self.suspended = None
                if target:
                    self._start(target, "user_request", chosen_by, now, detail)
                return
        # (c) a high-priority agenda item is due (reminders pause instead)
        for item in self._due_items(now):
            if running.paused or running.name == "notification":
                break
            if item.kind == "reminder" and running.manager is ManagerName.GENERAL:
                continue  # the menu and instructions are short: the reminder waits
            if item.kind == "reminder" and self.suspended is None:
                if self._interruption_allowed(running):
                    self._pause(running, "agenda", now, f"reminder {item.item_id}")
                    self.suspended = running
                    self.current = None
                    self._run_agenda_item(item, now)
                return
            if (
                item.kind == "event"
                and item.priority == "high"
                and self._interruption_allowed(running)
            ):
                self._cancel(running, "agenda", now, f"event {item.item_id} ({item.activity})")
                self._finish_user_activity(running, "stopped", now, ask_feedback=False)
                self.current = None
                self._run_agenda_item(item, now)
                return

    def _interruption_allowed(self, running: Running) -> bool:
        result = self._rule("AllowInterruption")
        return not (result is not None and "deny" in result.activate)

    # ------------------------------------------------------------------ steps 3-8: choose

    def _choose(self, now: datetime) -> None:
        ready = self._ready_user()
        session = self._session
        if session is not None and self._perception_unknown():
            return  # the user may still be there: start nothing until perception says
        if ready is None or session is None:
            if self._requests:
                asked = self._requests.pop(0)
                if asked.target:
                    self._start(asked.target, "user_request", asked.chosen_by, now, asked.detail)
                return
            behavior = self._motivated_behavior()
            self._start(
                behavior,
                "motivation",
                "motivation",
                now,
                f"dominant: {self._dominant() or 'none'}",
                why=Why(motivation=self._motivation_why()),
            )
            return
        if self._requests:
            asked = self._requests.pop(0)
            if asked.target:
                self._start(asked.target, "user_request", asked.chosen_by, now, asked.detail)
                return
        for item in self._due_items(now):
            self._run_agenda_item(item, now)
            return
        if self._ask_general_question(session, now):
            return
        if session.resume is not None:  # what she was doing when a session end cut it
            name, chosen_by, age = session.resume
            session.resume = None
            detail = f"cut {age:.0f} s ago when {session.user_id} left"
            if self._start(name, "resumed", chosen_by, now, detail):
                return
        # step 6: the user's proactivity is read before every choice, so the answer to
        # the question on initiative and what the user did since count from the first
        session.mode, session.p_user, session.mode_detail = self._choose_mode(self._profile())
        robot_turn, session.robot_turn = session.robot_turn, False
        draw = None if robot_turn else self.rng.random()
        mode = ModeWhy(p_user=session.p_user, draw=draw and round(draw, 4), mode=session.mode)
        if draw is not None and draw < session.p_user:
            self._start("menu", "user_choice", "user", now, session.mode_detail, why=Why(mode=mode))
            return
        self._robot_choice(session, now, mode)

    def _robot_choice(self, session: _Session, now: datetime, mode: ModeWhy | None = None) -> None:
        exclude = {session.last_activity} if session.last_activity else set()
        profile = self._profile()
        why = Why(
            mode=mode,
            preferences=self._preferences_why(profile),
            motivation=self._motivation_why(),
        )
        result = self._rule("ChooseEntertainment")
        if (
            result is not None
            and result.activate
            and result.activate[0] in ENTERTAINMENT_ACTIVITIES
        ):
            name = result.activate[0]
            why = why.model_copy(update={"rule": self._rule_why("ChooseEntertainment", result)})
            detail = f"rule ChooseEntertainment -> {name}"
            self._start(name, "preference", "robot", now, detail, why=why)
            return
        chooser = self.deps.chooser
        entertainment = self.managers[ManagerName.ENTERTAINMENT]
        assert hasattr(entertainment, "choose")
        if chooser is not None and profile is not None:
            name = entertainment.choose(
                self.rng, lambda rng, ex: chooser.choose(profile, rng, exclude=ex), exclude
            )
        else:
            name = entertainment.choose(self.rng, None, exclude)
        self._start(name, "preference", "robot", now, "predicted preference", why=why)

    def _ask_general_question(self, session: _Session, now: datetime) -> bool:
        bank = self.deps.questions
        profile = self._profile()
        if bank is None or profile is None:
            return False
        due = session.questions_left > 0 or (
            self.settings.question_every > 0
            and session.activities_done > 0
            and session.activities_done % self.settings.question_every == 0
            and session.last_activity is not None
            and f"after:{session.activities_done}" not in session.asked
        )
        if not due:
            return False
        session.asked.add(f"after:{session.activities_done}")
        question = bank.next_question(profile, self.rng, session.asked)
        if question is None:
            session.questions_left = 0
            return False
        session.asked.add(question.id)
        session.questions_left = max(0, session.questions_left - 1)
        self._question = question
        self._open_dialog(
            Dialog(
                DialogKind.GENERAL_QUESTION,
                question.text,
                tuple(question.choices or ()),
                now + timedelta(seconds=self.settings.question_timeout_s),
                {"question": question.id},
            ),
            now,
        )
        return True

    def _motivated_behavior(self) -> str:
        if self._motivation is None:
            return "wait"
        return self.deps.motivation.behavior(self._motivation)

    def _dominant(self) -> str | None:
        if self._motivation is None:
            return None
        return self.deps.motivation.dominant(self._motivation)

    # ------------------------------------------------------------------ agenda

    def _due_items(self, now: datetime) -> list[DueItem]:
        if self.deps.agenda is None or self._robot_blocked:  # offline: items wait (grace)
            return []
        return self._agenda_call("due", now, self._ready_user()) or []

    def _run_agenda_item(self, item: DueItem, now: datetime) -> None:
        if item.kind == "reminder":
            started = self._start(
                "notification",
                "agenda",
                "agenda",
                now,
                f"reminder {item.item_id}",
                args={"text": item.text or ""},
                agenda_item=item,
            )
        else:
            started = self._start(
                item.activity or "wait",
                "agenda",
                "agenda",
                now,
                f"event {item.item_id}",
                agenda_item=item,
            )
        if self.deps.agenda is not None:
            # Delivered once started (or failed to start): an item never runs twice.
            self._agenda_call("delivered", item, now)
        if not started:
            log.warning("agenda item %s did not start", item.item_id)

    def _agenda_call(self, method: str, *args: Any) -> Any:
        try:
            return getattr(self.deps.agenda, method)(*args)
        except Exception as error:  # the agenda's database may fail; the loop goes on
            log.exception("agenda.%s failed", method)
            self.deps.report_error("agenda", f"{method}: {error}")
            return None

    # ------------------------------------------------------------------ memory helpers

    def _profiles_call(self, method: str, *args: Any, **kwargs: Any) -> Any:
        if self.deps.profiles is None:
            return None
        return self.deps.profiles.call(method, *args, **kwargs)

    def _note_interaction(self, channel: str, answered: bool, now: datetime) -> None:
        if self._session is not None:
            channel = "screen" if channel == "screen" else "voice"
            self._profiles_call("record_interaction", self._session.user_id, channel, answered, now)

    def _note_initiative(self, took: bool, now: datetime) -> None:
        if self._session is not None:
            self._profiles_call("record_initiative", self._session.user_id, took, now)

    # ------------------------------------------------------------------ the robot link

    def _robot_unreachable(self, now: datetime) -> bool:
        """True while the robot is offline and no probe is due (once per tick).

        Offline (too many commands in a row not acknowledged), the robot starts nothing:
        an activity that only times out helps no one. Every so often one start is let
        through as a probe, the wait doubling from ``ack_timeout_s`` up to
        ``offline_retry_max_s``; feedback or the robot's token ends it at once.
        """
        settings = self.settings
        if not self.deps.expression.robot_offline:
            if self._probe_at is not None:
                self._probe_at = None
                self.deps.report_error("robot", "robot back online: activities start again")
            return False
        if self._probe_at is None:
            self._probe_wait_s = settings.ack_timeout_s
            self._probe_at = now + timedelta(seconds=self._probe_wait_s)
            self.deps.report_error(
                "robot",
                f"robot offline: {self.deps.expression.unacked_in_a_row} commands in a row"
                " not acknowledged; no activity starts until it answers",
            )
            return True
        if now < self._probe_at:
            return True
        self._probe_wait_s = min(2 * self._probe_wait_s, settings.offline_retry_max_s)
        self._probe_at = now + timedelta(seconds=self._probe_wait_s)
        return False

    # ------------------------------------------------------------------ output

    def _decide(
        self,
        action: DecisionAction,
        activity: str | None,
        reason: str,
        chosen_by: ChosenBy | None,
        detail: str | None,
        now: datetime,
        why: Why | None = None,
    ) -> None:
        self.counters.by_reason[reason] = self.counters.by_reason.get(reason, 0) + 1
        if why is None and action in ("cancel", "fail") and detail:
            why = Why(evidence=detail)
        if why is not None and why.motivation is None and reason.startswith("motivation"):
            why = why.model_copy(update={"motivation": self._motivation_why()})
        self._decisions.append(
            Decision(
                tick=self._tick,
                time=iso(now),
                action=action,
                activity=activity,
                manager=manager_of(activity).value if activity in ACTIVITIES else None,
                reason=reason,
                chosen_by=chosen_by,
                detail=detail,
                why=why,
            )
        )
        if self._session is not None and self._session.account is not None:
            self._session.account.on_decision(self._decisions[-1], now)

    # ------------------------------------------------------------------ why

    def _motivation_why(self) -> MotivationWhy | None:
        state = self._motivation
        if state is None:
            return None
        snapshot = MotivationSnapshot(**self.deps.motivation.snapshot(state))
        return MotivationWhy(dominant=snapshot.dominant, drives=snapshot.drives)

    @staticmethod
    def _rule_why(component: str, result: Any) -> RuleWhy:
        """The rule that decided: the first ``activate`` that ran, and where it stands."""
        where = result.activated_at[0] if getattr(result, "activated_at", ()) else None
        return RuleWhy(
            component=component,
            file=where.file if where is not None else None,
            line=where.line if where is not None else None,
            activate=list(result.activate),
        )

    def _preferences_why(self, profile: Profile | None) -> list[PreferenceWhy] | None:
        """The three activities the user is predicted to like best, with their scores."""
        chooser = self.deps.chooser
        if chooser is None or profile is None:
            return None
        beliefs = chooser.beliefs(profile)
        means = {
            name: a / (a + b)
            for name, (a, b) in beliefs.items()
            if name in ENTERTAINMENT_ACTIVITIES and a + b > 0
        }
        top = sorted(means, key=lambda name: -means[name])[:3]
        return [PreferenceWhy(activity=name, score=round(means[name], 3)) for name in top]

    def _activity_state(self, running: Running | None) -> _ActivityParts | None:
        """The fields of ActivityState, taken now (the active path moves on)."""
        if running is None:
            return None
        activity = self.managers[running.manager].activity
        return (
            running.name,
            str(running.manager),  # a StrEnum's text; ``.value`` is two Python calls
            "paused" if running.paused else "running",
            activity.state_path if activity is not None else "",
        )

    def build_state(self, now: datetime) -> DmsState:
        """The DmsState for ``now`` from what the controller holds."""
        return self._state_of(now).state()

    def _state_of(self, now: datetime) -> _TickState:
        """What DmsState for ``now`` is made of, taken now (the controller moves on)."""
        session = self._session
        user: tuple[str, bool, str, float] | None = None
        mode: Mode = "motivation"
        if session is not None:
            user_id = session.user_id
            proactivity = str(getattr(self._profile(), "proactivity", None) or "unknown")
            user = (user_id, self._ready_user() == user_id, proactivity, session.p_user)
            mode = session.mode
        snapshot = self._snapshot
        parts = (
            self.robot_id,
            self._tick,
            now,
            mode,
            user,
            self._activity_state(self.current),
            self._activity_state(self.suspended),
            snapshot.status if snapshot is not None else {},
            self.deps.expression.robot_offline,
        )
        return _TickState(parts, self.deps.motivation, self._motivation)

    @property
    def state(self) -> DmsState | None:
        """The state after the last tick."""
        return self._taken.state() if self._taken is not None else None

    @property
    def running_activity(self) -> Any:
        """The running activity object (for the behavior queryable), or None."""
        if self.current is None:
            return None
        return self.managers[self.current.manager].activity


def _motivation_snapshot(
    model: MotivationModel, state: MotivationState | None
) -> MotivationSnapshot:
    """DmsState's ``motivation`` for ``state`` (None: before the first step)."""
    if state is None:
        return MotivationSnapshot(dominant=None, drives={}, motivations={}, wellbeing=100.0)
    return MotivationSnapshot(**model.snapshot(state))


def _dms_state(
    robot: str,
    tick: int,
    now: datetime,
    mode: Mode,
    user: tuple[str, bool, str, float] | None,
    activity: _ActivityParts | None,
    suspended: _ActivityParts | None,
    inputs: Mapping[str, Any],
    offline: bool,
    motivation: MotivationSnapshot,
) -> DmsState:
    """The DmsState of the parts :meth:`Controller._state_of` took at a tick: ``user``
    is (id, ready, proactivity, p_user), an activity (name, manager, status, state)."""
    return DmsState(
        robot=robot,
        tick=tick,
        time=iso(now),
        mode=mode,
        user=(
            UserState(id=user[0], ready=user[1], proactivity=user[2], p_user=user[3])
            if user is not None
            else None
        ),
        activity=_activity_model(activity),
        suspended=_activity_model(suspended),
        motivation=motivation,
        inputs=dict(inputs),
        robot_link="offline" if offline else "ok",
    )


def _activity_model(parts: _ActivityParts | None) -> ActivityState | None:
    if parts is None:
        return None
    name, manager, status, state = parts
    return ActivityState(name=name, manager=manager, status=status, state=state)
