"""Users and sessions: who is in front of the robot, their profile, their session.

A session begins when perception says a user is ready and ends when the user is gone
(or unseen for ``perception_grace_s``). The profile is read off the tick; what the
session learns (answers, feedback, initiative, the activities done) goes to memory
through :class:`~dms.profiles.ProfileService`, which never blocks the tick.

A user id the store does not know becomes a profile only once it has been seen ready
and engaged for ``new_user_after_s``, and no more than ``new_profiles_per_hour`` new
profiles are made an hour (:class:`Newcomers`): a perception module that invents ids
(a flicker, a fault, a flood) must not fill the database. Until then the session goes
on with an empty profile, as with any new user, and what it learns is held here; it is
written when the user qualifies, and forgotten if she leaves before.

What the user answers counts at once: the profile read for a choice carries the fields
of the session's answers that the store does not show yet (its write is on its way, or
held), so a choice in the tick of an answer, and the ``why`` of that choice, use it.
"""

from __future__ import annotations

import logging
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import datetime, timedelta
from typing import Any

from dms.config import ControllerSettings
from dms.controller.deps import ControllerDeps, Counters, agenda_call
from dms.controller.running import Running
from dms.inputs import InputSnapshot
from dms.kernel import keys
from dms.kernel.activity_names import ACTIVITIES
from dms.kernel.clock import SteadyTime
from dms.kernel.messages import ChosenBy, Mode, Reason, UserPerception
from dms.kernel.session_metrics import SessionAccount
from memory import Profile, ProfileError, Question
from memory.profile import FIELDS, validate_fields

log = logging.getLogger(__name__)

NO_FEEDBACK_FOR = frozenset({"menu", "notification", "sleep", "wait", "instructions"})
"""Activities after which the robot does not ask how much the user liked them."""

ModeChoice = tuple[Mode, float, str | None]
"""A session's mode, the probability that the user takes the initiative, and why."""

DROP_REPORT_EVERY_S = 10.0
"""New users not stored for the hourly cap are counted and reported once in this long
(one line with the count), however many ids a flood brings."""

HELD_WRITES_MAX = 1000
"""Writes held for one user not yet stored; past it the later ones are dropped (a user
ready but never engaged for hours must not grow the daemon's memory without end)."""

_HOUR = timedelta(hours=1)
_SECOND = timedelta(seconds=1)


@dataclass
class Session:
    """One user's time in front of the robot."""

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
    newcomer: Profile | None = None
    """For a user the store does not know yet: the empty profile the session goes on with
    until she qualifies (None once she is stored, or for a known user)."""
    held: list[Callable[[], object]] = field(default_factory=list)
    """The writes of a newcomer's session, in order, sent when she qualifies."""
    engaged_since: datetime | None = None
    """Since when (steady time) a newcomer has been seen ready and engaged, without a
    break."""
    refused: bool = False
    """A newcomer over ``new_profiles_per_hour``: nothing of this session is stored."""
    answered: dict[str, Any] = field(default_factory=dict)
    """The fields this session's answers filled that the profile read does not show yet
    (the write is on its way to the store, or held for a newcomer): the choices that
    follow, and their ``why``, already use what the user said."""
    view: tuple[Profile, tuple[tuple[str, Any], ...], Profile] | None = None
    """The last profile read, the answers laid over it and the result: the same object
    while neither changes (the chooser caches its beliefs by profile)."""

    # The session's fields change only here: the choice and :class:`Sessions` tell it
    # what happened, and it keeps its own record.

    def set_mode(self, choice: ModeChoice) -> None:
        """Who takes the initiative, read again before every choice."""
        self.mode, self.p_user, self.mode_detail = choice

    def leave_turn_to_robot(self) -> None:
        """The user declined the menu (or did not answer it): the next pick is the robot's."""
        self.robot_turn = True

    def take_robot_turn(self) -> bool:
        """Whether the next pick was left to the robot; the turn is used up."""
        turn, self.robot_turn = self.robot_turn, False
        return turn

    def take_resume(self) -> tuple[str, ChosenBy, float] | None:
        """The activity a session end cut, to start again first; offered once."""
        resume, self.resume = self.resume, None
        return resume

    def question_due(self, every: int) -> bool:
        """Step 8's timing: the opening questions, then one after every ``every``
        activities (once for each such count, which is marked asked)."""
        done = self.activities_done
        due = self.questions_left > 0 or (
            every > 0
            and done > 0
            and done % every == 0
            and self.last_activity is not None
            and f"after:{done}" not in self.asked
        )
        if due:
            self.asked.add(f"after:{done}")
        return due

    def asked_question(self, question_id: str | None) -> None:
        """A general question was asked (None: the bank had none left for the user, so
        no opening question is left either)."""
        if question_id is None:
            self.questions_left = 0
            return
        self.asked.add(question_id)
        self.questions_left = max(0, self.questions_left - 1)

    def did(self, activity: str) -> None:
        """An activity the user may be asked about ended."""
        self.activities_done += 1
        self.last_activity = activity

    def engaged_for(self, now: datetime, engaged: bool) -> float:
        """Seconds (steady time) a newcomer has been seen ready and engaged, without a
        break, as of ``now``; 0 when not ``engaged`` now."""
        if not engaged:
            self.engaged_since = None
            return 0.0
        since = self.engaged_since = self.engaged_since or now
        return (now - since).total_seconds()

    def refuse(self) -> None:
        """A newcomer over the hourly cap: nothing of this session is stored."""
        self.refused = True
        self.held.clear()

    def mark_stored(self) -> None:
        """The newcomer qualified: her profile is being stored, and writes go out."""
        self.newcomer = None

    def take_held(self, session_id: str | None) -> list[Callable[[], object]]:
        """The stored newcomer's session has its key: the writes held until now, in order."""
        self.session_id = session_id
        held, self.held = self.held, []
        return held

    def hold(self, write: Callable[[], object]) -> None:
        """A write about a newcomer not stored yet, kept to be sent when she qualifies."""
        if len(self.held) < HELD_WRITES_MAX:
            self.held.append(write)
        elif len(self.held) == HELD_WRITES_MAX:
            log.warning("user %s not stored yet: later writes are dropped", self.user_id)
            self.held.append(lambda: None)  # warned once

    def with_answers(self, profile: Profile | None) -> Profile | None:
        """``profile`` with the fields of :attr:`answered` it does not show yet; an answer
        it shows has landed and is forgotten (a later change elsewhere then wins)."""
        if profile is None or not self.answered:
            return profile
        for name, value in list(self.answered.items()):
            if _field(profile, name) == value:
                del self.answered[name]
        if not self.answered:
            return profile
        answers = tuple(self.answered.items())
        view = self.view
        if view is not None and view[0] is profile and view[1] == answers:
            return view[2]
        update = {name: value for name, value in answers if name in FIELDS}
        attributes = {name: value for name, value in answers if name not in FIELDS}
        if attributes:
            update["attributes"] = {**profile.attributes, **attributes}
        result = profile.model_copy(update=update)
        self.view = (profile, answers, result)
        return result


class Newcomers:
    """The hourly cap on new profiles, and the one-line report of the ids it refused.

    Its times are steady (:meth:`Sessions.steady`): a wall clock set back an hour must
    not close the hour's window for an hour more.
    """

    def __init__(self, per_hour: int, report: Callable[[str, str], None]) -> None:
        self.per_hour = per_hour
        self.report = report
        self.made: deque[datetime] = deque()
        """When the new profiles of the last hour were made."""
        self.refused = 0
        """New ids refused since ``refused_since``, not yet reported."""
        self.refused_since: datetime | None = None

    def admit(self, now: datetime) -> bool:
        """Whether one more new profile may be made at ``now``; counts it if so."""
        while self.made and now - self.made[0] >= _HOUR:
            self.made.popleft()
        if len(self.made) < self.per_hour:
            self.made.append(now)
            return True
        self.refused += 1
        self.refused_since = self.refused_since or now
        return False

    def report_due(self, now: datetime) -> None:
        """Called every tick: report the ids refused over the last interval, once."""
        since = self.refused_since
        if since is None or (now - since).total_seconds() < DROP_REPORT_EVERY_S:
            return
        count, self.refused, self.refused_since = self.refused, 0, None
        self.report(
            keys.PERCEPTION_USER,
            f"{count} new user id{'s' if count != 1 else ''} not stored in the last "
            f"{(now - since).total_seconds():.0f} s: over new_profiles_per_hour = "
            f"{self.per_hour} (served without a profile)",
        )


class Sessions:
    """The user perceived at this tick and the session open with them."""

    def __init__(
        self, deps: ControllerDeps, settings: ControllerSettings, counters: Counters
    ) -> None:
        self.deps = deps
        self.settings = settings
        self.counters = counters
        self.session: Session | None = None
        self.snapshot: InputSnapshot | None = None
        self.user: UserPerception | None = None
        """``perception/user`` at this tick; None if stale or missing."""
        self._unknown_since: datetime | None = None
        """Steady time since when perception has not said who is there."""
        self.newcomers = Newcomers(settings.new_profiles_per_hour, deps.report_error)
        self.clock = SteadyTime()
        """Takes the wall clock's steps out of the tick's ``now`` (:meth:`steady`)."""
        self._last_cut: tuple[str, str, datetime, timedelta] | None = None
        """The last activity a session end cut here: user, activity, when (wall time) and
        the steps of the wall clock until then (``clock.offset``)."""

    def see(self, snapshot: InputSnapshot, now: datetime, monotonic: float) -> None:
        """Take this tick's inputs, and its time on both clocks (for :meth:`steady`)."""
        self.clock.observe(now, monotonic)
        self.snapshot = snapshot
        user = snapshot.values.get(keys.PERCEPTION_USER)
        self.user = user if isinstance(user, UserPerception) else None

    def steady(self, now: datetime) -> datetime:
        """This tick's ``now`` on the steady clock (:class:`~dms.kernel.clock.SteadyTime`).

        What measures a duration reads it (grace periods, dialog deadlines, the menu's
        and the activities' waits, the robot's commands), so that setting the wall clock
        changes no decision; what names a time (the profile's session and run times, the
        agenda, the decision log) keeps the wall time ``now``.
        """
        return self.clock.steady(now)

    # ------------------------------------------------------------------ who is there

    def ready_user(self) -> str | None:
        """The id of the user present and ready to interact, if any."""
        user = self.user
        if user is not None and user.present and user.ready and user.user_id:
            return user.user_id
        return None

    def perception_unknown(self) -> bool:
        """``perception/user`` is stale or missing: who is there is unknown (not "nobody")."""
        return self.snapshot is not None and keys.PERCEPTION_USER not in self.snapshot.values

    def departure(self, now: datetime) -> tuple[Reason, str] | None:
        """Whether the session ends now, and why: its user is gone, or went unperceived
        for ``perception_grace_s`` (a missing input is not considered: until then the
        session and its activity go on, and nothing new starts)."""
        session = self.session
        if session is None:
            self._unknown_since = None
            return None
        if self.perception_unknown():
            now = self.steady(now)
            since = self._unknown_since = self._unknown_since or now
            grace_s = self.settings.perception_grace_s
            if (now - since).total_seconds() < grace_s:
                return None
            self._unknown_since = None
            return "input_missing", f"no perception of {session.user_id} for {grace_s:g} s"
        self._unknown_since = None
        if not self._gone(session.user_id):
            return None
        return "user_left", f"{session.user_id} is gone"

    def _gone(self, user_id: str) -> bool:
        user = self.user
        if user is None:
            return True
        return not user.present or (user.user_id is not None and user.user_id != user_id)

    def is_the_user(self, by: str | None) -> bool:
        """A request ``by`` the user in front of the robot (``"user"`` or their id)."""
        session = self.session
        return by is not None and session is not None and by in ("user", session.user_id)

    @property
    def user_id(self) -> str | None:
        """The session's user, if a session is open."""
        return self.session.user_id if self.session is not None else None

    def account(self) -> SessionAccount | None:
        """The open session's metrics, if any."""
        return self.session.account if self.session is not None else None

    # ------------------------------------------------------------------ begin and end

    def begin(
        self, user_id: str, now: datetime, choose_mode: Callable[[Profile | None], ModeChoice]
    ) -> None:
        """Open a session for ``user_id``: load their profile, choose the mode."""
        newcomer = None
        if self._stored(user_id):
            profile = self._load_profile(user_id, now)
            session_id = self.profiles_call("start_session", user_id, now)
        else:  # what a new profile would be; nothing is stored until she qualifies
            profile = newcomer = Profile(user_id=user_id, created_at=now, updated_at=now, version=1)
            session_id = None
            self._newcomer(user_id)
        agenda_call(self.deps, "user_perceived", user_id, now)
        # read before the mode's rule, which reads nothing of the store
        resume = self._cut_to_resume(user_id, now) if newcomer is None else None
        # the session first, so that ChooseMode sees params.user (the profile and its id)
        self.session = session = Session(
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
            newcomer=newcomer,
            resume=resume,
        )
        session.set_mode(choose_mode(profile))
        log.info("user %s is ready (mode %s)", user_id, session.mode)

    def admit(self, now: datetime) -> None:
        """Called every tick after the session's begin or end: store a newcomer seen
        ready and engaged for ``new_user_after_s`` (within ``new_profiles_per_hour``),
        and report the newcomers the cap refused."""
        now = self.steady(now)  # only durations here: nothing is named by this time
        self.newcomers.report_due(now)
        session = self.session
        if session is None or session.newcomer is None or session.refused:
            return
        user = self.user
        if user is None or user.user_id != session.user_id:
            return  # unknown or somebody else: departure() sees to it
        engaged = user.present and user.ready and _engaged(user)
        if session.engaged_for(now, engaged) < self.settings.new_user_after_s or not engaged:
            return
        if self._stored(session.user_id) or self.newcomers.admit(now):
            self._store_newcomer(session)
            return
        session.refuse()
        self._newcomer(None)
        log.debug("user %s not stored: over new_profiles_per_hour", session.user_id)

    def _store_newcomer(self, session: Session) -> None:
        """Make the newcomer's profile and session as of the session's start, then send
        what the session held, in order."""
        user_id, started = session.user_id, session.started
        session.mark_stored()
        self._newcomer(None)
        self._load_profile(user_id, started)
        session_id = self.profiles_call("start_session", user_id, started)
        held = session.take_held(session_id if isinstance(session_id, str) else None)
        for write in held:
            write()
        log.info("user %s is new: profile stored", user_id)

    def _newcomer(self, user_id: str | None) -> None:
        if self.deps.profiles is not None:
            self.deps.profiles.meet_newcomer(user_id)

    def _stored(self, user_id: str) -> bool:
        """Whether the store has a profile for ``user_id`` (or one is being written).
        Without memory every user is taken as known: there is nothing to protect."""
        profiles = self.deps.profiles
        if profiles is None or profiles.cached(user_id) is not None:
            return True
        return profiles.stored(user_id) is True

    def end(self, now: datetime) -> None:
        """Close the session: store it with its metrics; the chooser may retrain."""
        session = self.session
        self.session = None
        if session is not None and session.newcomer is not None:
            self._newcomer(None)
            log.debug(
                "user %s left before being stored: %d writes forgotten",
                session.user_id,
                len(session.held),
            )
        if session is not None and session.session_id is not None:
            metrics = None
            if session.account is not None:
                counters = self.counters
                metrics = session.account.result(
                    now, misheard=counters.misheard, unanswered=counters.unanswered
                )
            self.profiles_call("end_session", session.session_id, now, metrics=metrics)
        if session is not None and self.deps.chooser is not None:
            self.deps.chooser.session_ended(now)  # retrains in the background, if due

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
        since = now - ended
        cut = self._last_cut
        if cut is not None and cut[:2] == (user_id, name) and abs(ended - cut[2]) < _SECOND:
            # the cut was here: the wall clock's steps since do not count (a cut at
            # another robot, or before a restart, has only the wall time the store keeps)
            since -= self.clock.offset - cut[3]
        age = since.total_seconds()
        if not 0 <= age <= window:
            return None
        chosen_by = last.get("chosen_by")
        return str(name), chosen_by if chosen_by in ("robot", "user") else "robot", age

    # ------------------------------------------------------------------ the profile

    def _load_profile(self, user_id: str, now: datetime) -> Profile | None:
        """Read off the tick: a healthy database answers within the tick (LOAD_WAIT_S);
        else the session begins at once on the cached (or an empty) profile, and the
        profile is used as soon as it lands (the user is not kept waiting)."""
        if self.deps.profiles is None:
            return None
        return self.deps.profiles.load(user_id, now)

    def profile(self) -> Profile | None:
        """The session's user's profile as cached (a newcomer's empty one until she is
        stored), with the session's answers the store has not shown yet; None without a
        session."""
        session = self.session
        if self.deps.profiles is None or session is None:
            return None
        if session.newcomer is not None:
            return session.with_answers(session.newcomer)
        return session.with_answers(self.deps.profiles.cached(session.user_id))

    def record_answer(self, question: Question, answer: str, now: datetime) -> None:
        """Store the answer to a general question; the fields it fills count from now on,
        before the write lands (the daemon writes off the tick; a newcomer's is held)."""
        session = self.session
        if session is None:
            return
        bank = self.deps.questions
        fields = bank.parse(question, answer) if bank is not None else None
        try:  # checked as the store will: the value it will show, or none if it refuses
            columns, attributes = validate_fields(fields or {})
        except ProfileError:
            columns, attributes = {}, {}
        session.answered.update(columns)
        session.answered.update(attributes)
        self.profiles_call("record_answer", session.user_id, question.id, answer, now)

    def style(self) -> str:
        """How the user likes to be asked: ``voice`` or ``screen`` (Table 2)."""
        profile = self.profile()
        return str(getattr(profile, "interaction_style", None) or "voice")

    def profiles_call(self, method: str, *args: Any, **kwargs: Any) -> Any:
        """A write to memory, queued off the tick; None without memory. A write about the
        session's user while she is not stored is held (or dropped, if she never will be)."""
        if self.deps.profiles is None:
            return None
        session = self.session
        if session is not None and args and args[0] == session.user_id:
            if session.refused:
                return None
            if session.newcomer is not None:
                session.hold(lambda: self.profiles_call(method, *args, **kwargs))
                return None
        return self.deps.profiles.call(method, *args, **kwargs)

    # ------------------------------------------------------------------ what the session learns

    def note_interaction(self, channel: str, answered: bool, now: datetime) -> None:
        """A dialog closed, ``answered`` or not: counted (the session's metrics read the
        count) and, with a session, written to the user's profile."""
        if not answered:
            self.counters.count_unanswered()
        if self.session is not None:
            channel = "screen" if channel == "screen" else "voice"
            self.profiles_call("record_interaction", self.session.user_id, channel, answered, now)

    def note_initiative(self, took: bool, now: datetime) -> None:
        """The user took a chance to choose (``took``) or let it pass: their proactivity."""
        if self.session is not None:
            self.profiles_call("record_initiative", self.session.user_id, took, now)

    def left_to_robot(self, now: datetime, unanswered: bool) -> None:
        """The user let the menu's choice pass (said "you choose", or did not answer in
        time: ``unanswered``): their proactivity, and the next pick is the robot's."""
        if unanswered:
            self.counters.count_unanswered()
        self.note_initiative(False, now)
        if self.session is not None:
            self.session.leave_turn_to_robot()

    def record_activity(self, running: Running, outcome: str, now: datetime) -> bool:
        """Store what became of the session user's activity; True if it counts as one the
        user may be asked about (not the menu, a notification or an idle behavior)."""
        session = self.session
        if session is None or running.user_id != session.user_id or running.name == "menu":
            return False
        # Both ends are named by the wall clock; set back during the run, it would name an
        # end before the start, which the store refuses: the start is then named the end.
        started = min(running.started, now)
        run = (running.name, started, now, outcome, running.chosen_by or "robot")
        if outcome == "cut":
            self._last_cut = (session.user_id, running.name, now, self.clock.offset)

        def write() -> None:  # the session's id read when sent: a newcomer's comes later
            self.profiles_call(
                "record_activity",
                session.user_id,
                *run,
                outcome == "cancelled",
                session.session_id,
            )

        if session.newcomer is not None and not session.refused:
            session.hold(write)
        else:
            write()
        if running.name in NO_FEEDBACK_FOR:
            return False
        session.did(running.name)
        return True


def _field(profile: Profile, name: str) -> Any:
    """A field's value, or a free attribute's."""
    return getattr(profile, name) if name in FIELDS else profile.attributes.get(name)


def _engaged(user: UserPerception) -> bool:
    """Perception does not say the user is disengaged: engagement unknown or above 0."""
    return user.engagement is None or user.engagement > 0
