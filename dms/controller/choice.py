"""What the robot does next: the heart of the paper's decision loop.

Read this file first. The tick (``tick.py``) calls, in order:

- :meth:`Choice.follow_user`: is a user ready? A session begins (step 5: the profile
  is loaded or created) or ends (the user left);
- :meth:`Choice.check_cancel_reasons`: while an activity runs, the paper's reasons to
  cancel it, (a) to (c) in order (step 2); a menu nobody answers ends here too, as (d);
- :meth:`Choice.follow_activity`: what the running activity did, unless a reason above
  cancelled it: reason (d), it failed or asked for another; after it, the robot may ask
  how much the user liked it (step 7);
- :meth:`Choice.check_agenda_in_dialog`: while a question waits for its answer, a due
  agenda item interrupts it as reason (c) interrupts an activity;
- :meth:`Choice.choose`: with nothing running, with no user the behavior of the dominant
  motivation (step 4); with a user, a due agenda item, now and then a general question
  (step 8), else an activity chosen by the user's proactivity (step 6).

Each takes the tick's wall time ``now``: it names the decisions and what the profile
and the agenda are told. What measures a duration (a dialog's deadline, the menu's
timeout) reads the steady time instead (:meth:`Sessions.steady`), which a wall clock set
back or forward does not move.

The choice decides and asks its collaborators to act; it writes none of their state.
The runner moves and clears the activities, the dialogs open and hold the questions, the
session keeps its own record; requests come from the events through a queue.
"""

from __future__ import annotations

import logging
import random
from collections.abc import Callable, Collection, Mapping
from datetime import datetime
from typing import TYPE_CHECKING, Any

from agenda import DueItem
from dms.config import ControllerSettings
from dms.controller.decisions import choice_why, rule_why
from dms.controller.deps import ControllerDeps, agenda_call
from dms.controller.dialogs import Dialogs
from dms.controller.drives import Drives
from dms.controller.requests import Requests
from dms.controller.running import Runner, Running
from dms.controller.sessions import ModeChoice, Session, Sessions
from dms.dialog import feedback_dialog
from dms.kernel.activity_names import ACTIVITIES, ENTERTAINMENT_ACTIVITIES, ManagerName
from dms.kernel.messages import (
    ChosenBy,
    Mode,
    ModeWhy,
    PreferenceWhy,
    Reason,
    Why,
)
from managers import ManagerStatus
from memory import Profile

if TYPE_CHECKING:
    from memory.preferences import ChoiceDraw

log = logging.getLogger(__name__)

MODE_BY_PROACTIVITY: dict[str, Mode] = {
    "high": "user_choice",
    "low": "autonomous",
    "moderate": "hybrid",
    "unknown": "hybrid",
}
RULE_MODES: dict[str, float] = {"autonomous": 0.0, "user_choice": 1.0, "hybrid": 0.5}
"""A ``ChooseMode`` activation and the probability that the user takes the initiative."""


class Choice:
    """The decisions of steps 2 to 8; see the module docstring."""

    def __init__(
        self,
        deps: ControllerDeps,
        settings: ControllerSettings,
        rng: random.Random,
        drives: Drives,
        sessions: Sessions,
        runner: Runner,
        dialogs: Dialogs,
        requests: Requests,
        rule: Callable[[str], Any],
    ) -> None:
        """``requests``: what the events were asked, taken at the decision points;
        ``rule(component)`` evaluates a DMSL rule component (None: no rules)."""
        self.deps = deps
        self.settings = settings
        self.rng = rng
        self.drives = drives
        self.sessions = sessions
        self.runner = runner
        self.dialogs = dialogs
        self.requests = requests
        self.rule = rule
        self.reminder: Running | None = None
        """The notification that interrupted an activity, a menu or a dialog, which
        comes back when it ends (see :meth:`_back_after`)."""
        self.menu_again = False
        """The reminder cut the menu: it is offered again after it."""
        self.menu_offered: datetime | None = None
        """When (steady time) the menu was first offered (offered again after a reminder,
        it keeps its first time): ``menu_timeout_s`` counts from then."""

    # ------------------------------------------------------------------ steps 3 and 5: the user

    def follow_user(self, now: datetime) -> None:
        """End the session of a user who left (what runs for them is cut), and begin one
        for a user who is ready."""
        sessions, runner = self.sessions, self.runner
        ready = sessions.ready_user()
        departure = sessions.departure(now)
        session = sessions.session
        if session is not None and departure is not None:
            reason, why = departure
            # leaving (or going unseen) says nothing of what the user thought of the
            # activity: the session's end cut it (only the user's own stop counts), and
            # a robot that sees her again may resume it (resume_cut_within_s)
            for running in (runner.current, runner.suspended):
                if running is not None and running.user_id == session.user_id:
                    runner.cancel(running, reason, now, why)
                    sessions.record_activity(running, "cut", now)
            if self.dialogs.dialog is not None:
                self.dialogs.end(now)
            self._forget_interrupted()
            sessions.end(now)
        if sessions.session is None and ready is not None:
            sessions.begin(ready, now, self.choose_mode)
        sessions.admit(now)  # a new user is stored once she qualifies

    # ------------------------------------------------------------------ step 7: after an activity

    def follow_activity(self, now: datetime) -> None:
        """Tick the running activity; when it ends, record it, maybe ask for feedback,
        follow where it redirects, and resume what a reminder paused."""
        runner = self.runner
        running = runner.current
        if running is None:
            return
        # an activity that ended is no longer current; the runner said how it ended
        reply = runner.follow(running, now)
        if reply.status in (ManagerStatus.RUNNING, ManagerStatus.PAUSED, ManagerStatus.IDLE):
            return  # idle: the manager lost it, and the next choice starts afresh
        if reply.status is ManagerStatus.FAILED:
            self.sessions.record_activity(running, "failed", now)
        elif reply.status is ManagerStatus.COMPLETED:
            if running.name == "menu" and not reply.redirect and self.sessions.session:
                # offered the choice, left it to the robot
                self.sessions.left_to_robot(now, unanswered=False)
            self._completed(running, now, ask_feedback=not reply.redirect)
            if reply.redirect is not None and reply.redirect in ACTIVITIES:  # else: said so
                self._follow_redirect(running, reply.redirect, now)
        elif reply.status is ManagerStatus.CANCELLED:
            self.sessions.record_activity(running, "cancelled", now)
        if runner.current is None and (running is self.reminder or runner.suspended is not None):
            self._back_after(running.name, now)

    def _completed(self, running: Running, now: datetime, ask_feedback: bool) -> None:
        """Record a completed activity and, now and then, ask how much the user liked it."""
        counts = self.sessions.record_activity(running, "completed", now)
        if not (counts and ask_feedback):
            return
        coin, chance = self.rng.random(), self.settings.feedback_probability
        if coin < chance:
            steady = self.sessions.steady(now)
            seen = f"{running.name} completed and the feedback coin {coin:.4f} fell under {chance}"
            self.dialogs.open(
                feedback_dialog(running.name, steady, self.settings.question_timeout_s),
                now,
                Why(evidence=seen),
            )

    def _follow_redirect(self, running: Running, target: str, now: datetime) -> None:
        if running.name == "menu":
            self.sessions.note_initiative(True, now)
            self._start(target, "user_choice", "user", now, "chosen from the menu")
        else:
            self._start(
                target, "activity_redirect", running.chosen_by, now, f"asked for by {running.name}"
            )

    # ------------------------------------------------------------------ step 2: cancel reasons

    def check_cancel_reasons(self, now: datetime) -> None:
        """The paper's reasons to cancel the running activity, in its order."""
        runner = self.runner
        running = runner.current
        assert running is not None
        ready = self.sessions.ready_user()
        # (a) no user interacts and the dominant motivation changed
        if running.chosen_by == "motivation":
            if ready is not None:
                runner.cancel(running, "user_arrived", now, f"{ready} is ready to interact")
                return
            wanted = self.drives.behavior()
            if wanted != running.name and self._interruption_allowed():
                dominant = self.drives.dominant() or "none"
                runner.cancel(running, "motivation_changed", now, f"now {dominant} dominates")
                return
        # (b) the user asked to change
        asked = self.requests.take()
        if asked is not None:
            target, chosen_by, detail = asked.target, asked.chosen_by, asked.detail
            if target != running.name:
                runner.cancel(running, "user_request", now, detail)
                # an app's or a caregiver's stop says nothing of what the user likes
                outcome = "cancelled" if asked.own else "stopped"
                self.sessions.record_activity(running, outcome, now)
                if runner.suspended is not None:
                    runner.cancel(runner.suspended, "user_request", now, detail)
                self._forget_interrupted()
                if target:
                    self._start(target, "user_request", chosen_by, now, detail)
                return
        # (c) a high-priority agenda item is due (reminders pause instead)
        for item in self.due_items(now):
            if running.paused or running.name == "notification":
                break
            if item.kind == "reminder" and running.name == "instructions":
                continue  # short, and said once: the reminder waits for its end
            if item.kind == "reminder" and runner.suspended is None:
                if self._interruption_allowed():
                    detail = f"reminder {item.item_id}"
                    if running.name == "menu":
                        # one activity at a time on the general manager, as the
                        # reminder: the menu stops, and is offered again after it
                        runner.cancel(running, "agenda", now, detail, cleanup=False)
                        self.menu_again = True
                    else:
                        runner.suspend(running, "agenda", now, detail)
                    self.dialogs.forget_held()
                    self._remind(item, now)
                return
            if item.kind == "event" and item.priority == "high" and self._interruption_allowed():
                runner.cancel(running, "agenda", now, f"event {item.item_id} ({item.activity})")
                self.sessions.record_activity(running, "stopped", now)
                self._run_agenda_item(item, now)
                return
        # (d) a menu nobody answers fails: the user is not answering (the paper's Table 4);
        # an activity that failed or asked for another: follow_activity, next, sees to it
        if running.name == "menu":
            self._menu_unanswered(running, now)

    def _menu_unanswered(self, running: Running, now: datetime) -> bool:
        """End the menu if it has had no answer for ``menu_timeout_s`` (since it was
        first offered, a reminder in between or not, or since the user last tried to
        answer); True if it ended.

        A user who does not answer counts in the session's ``user_not_answering`` and
        let the choice pass: the robot chooses next, as after "you choose".
        """
        limit = self.settings.menu_timeout_s
        steady = self.sessions.steady(now)
        offered = self.menu_offered or steady
        taken = self.runner.taken_at
        since = max(offered, taken) if taken is not None else offered
        if running.paused or (steady - since).total_seconds() < limit:
            return False
        self.runner.cancel(running, "user_choice", now, f"no answer in {limit:g} s")
        self.sessions.left_to_robot(now, unanswered=True)
        return True

    def _interruption_allowed(self) -> bool:
        result = self.rule("AllowInterruption")
        return not (result is not None and "deny" in result.activate)

    # ------------------------------------------------------------------ steps 3-8: choose

    def choose(self, now: datetime) -> None:
        """Nothing runs and no dialog is open: choose what the robot does."""
        ready = self.sessions.ready_user()
        session = self.sessions.session
        if session is not None and self.sessions.perception_unknown():
            return  # the user may still be there: start nothing until perception says
        if self.runner.blocked and self.runner.failing is not None:
            # an output channel fails: only what the user asks for by name is tried until
            # the next probe (no question, no menu, no pick of the robot's only to fail)
            asked = self.requests.take()
            if asked is not None and asked.target:
                self._start(asked.target, "user_request", asked.chosen_by, now, asked.detail)
            return
        if ready is None or session is None:
            # step 4: no user ready, the behavior of the dominant motivation (or a request)
            asked = self.requests.take()
            if asked is not None:
                if asked.target:
                    self._start(asked.target, "user_request", asked.chosen_by, now, asked.detail)
                return
            self._start(
                self.drives.behavior(),
                "motivation",
                "motivation",
                now,
                f"dominant: {self.drives.dominant() or 'none'}",
                why=Why(motivation=self.drives.why()),
            )
            return
        asked = self.requests.take()
        if asked is not None and asked.target:
            self._start(asked.target, "user_request", asked.chosen_by, now, asked.detail)
            return
        # step 6: an agenda item that is due
        for item in self.due_items(now):
            self._run_agenda_item(item, now)
            return
        # step 8: now and then a general question
        if self._ask_general_question(session, now):
            return
        resume = session.take_resume()
        if resume is not None:  # what she was doing when a session end cut it
            name, chosen_by, age = resume
            detail = f"cut {age:.0f} s ago when {session.user_id} left"
            if self._start(name, "resumed", chosen_by, now, detail):
                return
        # step 6: the user's proactivity is read before every choice, so the answer to
        # the question on initiative and what the user did since count from the first
        session.set_mode(self.choose_mode(self.sessions.profile()))
        robot_turn = session.take_robot_turn()
        draw = None if robot_turn else self.rng.random()
        # the coin unrounded: it is compared with p_user, and rounding could flip it
        mode = ModeWhy(
            p_user=session.p_user,
            draw=draw,
            mode=session.mode,
            left_to_robot=True if robot_turn else None,
        )
        if draw is not None and draw < session.p_user:
            self._start("menu", "user_choice", "user", now, session.mode_detail, why=Why(mode=mode))
            return
        self._robot_choice(session, now, mode)

    def choose_mode(self, profile: Profile | None) -> ModeChoice:
        """Who takes the initiative: a ``ChooseMode`` rule, else the user's proactivity."""
        result = self.rule("ChooseMode")
        if result is not None and result.activate and result.activate[0] in RULE_MODES:
            chosen = result.activate[0]
            mode: Mode = chosen
            return mode, RULE_MODES[chosen], f"rule ChooseMode -> {chosen}"
        proactivity = str(getattr(profile, "proactivity", None) or "unknown")
        p_user = self.settings.user_initiative.get(proactivity, 0.5)  # type: ignore[call-overload]
        return MODE_BY_PROACTIVITY.get(proactivity, "hybrid"), p_user, None

    def _robot_choice(self, session: Session, now: datetime, mode: ModeWhy | None = None) -> None:
        """The robot picks: a ``ChooseEntertainment`` rule, else the activity the user is
        predicted to like (never the last one twice in a row)."""
        exclude = {session.last_activity} if session.last_activity else set()
        profile = self.sessions.profile()
        why = Why(
            mode=mode,
            preferences=self._preferences_why(profile),
            motivation=self.drives.why(),
        )
        result = self.rule("ChooseEntertainment")
        if (
            result is not None
            and result.activate
            and result.activate[0] in ENTERTAINMENT_ACTIVITIES
        ):
            name = result.activate[0]
            why = why.model_copy(update={"rule": rule_why("ChooseEntertainment", result)})
            detail = f"rule ChooseEntertainment -> {name}"
            self._start(name, "preference", "robot", now, detail, why=why)
            return
        chooser = self.deps.chooser
        entertainment = self.runner.managers[ManagerName.ENTERTAINMENT]
        assert hasattr(entertainment, "choose")
        if chooser is not None and profile is not None:
            draws: list[ChoiceDraw] = []

            def draw(rng: random.Random, excluded: Collection[str]) -> str:
                drawn = chooser.choose(profile, rng, exclude=excluded)
                draws.append(drawn)
                return drawn.activity

            name = entertainment.choose(self.rng, draw, exclude)
            choice = choice_why(exclude, draws[-1] if draws else None)
        else:
            name = entertainment.choose(self.rng, None, exclude)
            choice = choice_why(exclude, None)
        why = why.model_copy(update={"choice": choice})
        self._start(name, "preference", "robot", now, "predicted preference", why=why)

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

    def _ask_general_question(self, session: Session, now: datetime) -> bool:
        """Step 8: the session's opening questions, then one every ``question_every``
        activities; True if a question is asked."""
        bank = self.deps.questions
        profile = self.sessions.profile()
        if bank is None or profile is None:
            return False
        if not session.question_due(self.settings.question_every):
            return False
        question = bank.next_question(profile, self.rng, session.asked)
        session.asked_question(question.id if question is not None else None)
        if question is None:
            return False
        self.dialogs.ask_question(question, now)
        return True

    # ------------------------------------------------------------------ the agenda

    def due_items(self, now: datetime) -> list[DueItem]:
        """The agenda items due now for the ready user (none while the robot is offline:
        they wait, within their grace)."""
        if self.deps.agenda is None or self.runner.blocked:
            return []
        user = self.sessions.ready_user()
        return agenda_call(self.deps, "due", lambda agenda: agenda.due(now, user)) or []

    def check_agenda_in_dialog(self, now: datetime) -> None:
        """A dialog is open: a due agenda item interrupts it as it would an activity.

        A reminder is said at once and the question asked again after it (a paused
        activity "continue or stop?" is about stays paused until the answer); a
        high-priority event drops the question (and the activity paused for it) and
        starts. Other items wait for the dialog to end.
        """
        runner, dialogs = self.runner, self.dialogs
        dialog = dialogs.dialog
        if dialog is None or runner.suspended is not None:
            return
        for item in self.due_items(now):
            if item.kind == "event" and item.priority != "high":
                continue
            if not self._interruption_allowed():
                return
            paused = runner.current  # the activity "continue or stop?" is about, if any
            detail = f"{item.kind} {item.item_id} during the {dialog.kind.value} dialog"
            if item.kind == "reminder":
                dialogs.hold(now)
                runner.set_aside()
                self._remind(item, now)
                return
            dialogs.end(now)
            if paused is not None:
                runner.cancel(paused, "agenda", now, detail)
                self.sessions.record_activity(paused, "stopped", now)
            self._run_agenda_item(item, now)
            return

    def _remind(self, item: DueItem, now: datetime) -> None:
        """Say a reminder over what it interrupted (suspended, held or cut before)."""
        self._run_agenda_item(item, now)
        self.reminder = self.runner.current
        if self.reminder is None:  # it did not start: what it interrupted comes back
            self._back_after("reminder", now)

    def _back_after(self, what: str, now: datetime) -> None:
        """What a reminder interrupted comes back when it ends: the activity resumes, the
        question is asked again, the menu is offered again."""
        suspended = self.runner.restore()  # still paused
        menu_again, self.menu_again = self.menu_again, False
        self.reminder = None
        if self.dialogs.held is not None:  # the question is about the paused activity
            self.dialogs.ask_again(now)
        elif suspended is not None:
            self.runner.resume(suspended, "agenda", now, f"after the {what}")
        elif menu_again:
            self._offer_menu_again(what, now)

    def _offer_menu_again(self, what: str, now: datetime) -> None:
        """After the reminder that cut it, the menu comes back for the rest of its time:
        ``menu_timeout_s`` counts from its first offer, so that no reminder leaves the
        user longer unanswered. Its time up, the robot chooses, as after no answer."""
        first = self.menu_offered
        steady = self.sessions.steady(now)
        if first is not None and (steady - first).total_seconds() >= self.settings.menu_timeout_s:
            self.sessions.left_to_robot(now, unanswered=True)
            return
        self._start("menu", "user_choice", "user", now, f"offered again after the {what}")
        self.menu_offered = first or self.menu_offered

    def _forget_interrupted(self) -> None:
        """What a reminder interrupted does not come back (the user asked for something
        else, or left)."""
        self.reminder = None
        self.menu_again = False
        self.dialogs.forget_held()

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
        # Delivered once started (or failed to start): an item never runs twice.
        agenda_call(self.deps, "delivered", lambda agenda: agenda.delivered(item, now))
        if not started:
            log.warning("agenda item %s did not start", item.item_id)

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
        """Start ``name`` for the session's user (if any); False if it did not start."""
        started = self.runner.start(
            name, reason, chosen_by, now, self.sessions.user_id, detail, args, agenda_item, why
        )
        if started and name == "menu":
            self.menu_offered = self.sessions.steady(now)
        return started
