"""Dialogs: the robot asks, the user answers (or not) by voice or on the screen.

Three kinds: a general question (to know the user better), the feedback question after
an activity ("how much did you like it?"), and "continue or stop?" when the user touches
the robot's right shoulder during an activity (the activity waits, paused, for the
answer). One dialog is open at a time; while it is, nothing new is chosen.

The user may ask for an activity instead of answering (the request wins, the dialog
closes), and a reminder may fall due: the dialog is held, silent, while the reminder is
said, then asked again (see ``choice.py``).

The methods here take the tick's wall time ``now``, which names what is written (the
answers, the decision log); a dialog's own times are steady (:meth:`Sessions.steady`).
:class:`Dialogs` alone writes which dialog is open and which is held.
"""

from __future__ import annotations

from datetime import datetime, timedelta

from dms.config import ControllerSettings
from dms.controller.decisions import DecisionLog
from dms.controller.running import Runner
from dms.controller.sessions import Sessions
from dms.dialog import CONFIRM_STOP, Dialog, DialogKind, feedback_score
from dms.dialog import SOURCE as DIALOG_SOURCE
from dms.kernel.expression import ExpressionArbiter
from dms.kernel.messages import Why
from memory import Question


class Dialogs:
    """The open dialog, and what its answer does."""

    def __init__(
        self,
        expression: ExpressionArbiter,
        settings: ControllerSettings,
        log: DecisionLog,
        sessions: Sessions,
        runner: Runner,
    ) -> None:
        self.expression = expression
        self.settings = settings
        self.log = log
        self.sessions = sessions
        self.runner = runner
        self.dialog: Dialog | None = None
        self.question: Question | None = None
        """The general question the open dialog asks, if it asks one."""
        self.held: tuple[Dialog, Question | None] | None = None
        """The dialog a reminder interrupted (and its general question), asked again
        after the reminder."""

    def open(self, dialog: Dialog, now: datetime, why: Why | None = None) -> None:
        """Ask ``dialog``'s question in the user's style and note the decision to ask
        (``why``: what decided to ask, when the caller knows more than the question)."""
        self.dialog = dialog
        dialog.ask(self.expression, self.sessions.steady(now), self.sessions.style())
        activity = dialog.context.get("activity")
        self.log.decide("ask", activity, dialog.kind.value, None, dialog.question, now, why)

    def ask_question(self, question: Question, now: datetime) -> None:
        """Open a dialog on a general question of the question bank."""
        self.question = question
        self.open(
            Dialog(
                DialogKind.GENERAL_QUESTION,
                question.text,
                tuple(question.choices or ()),
                self.sessions.steady(now) + timedelta(seconds=self.settings.question_timeout_s),
                {"question": question.id, "field": question.field},
            ),
            now,
        )

    def advance(self, now: datetime) -> None:
        """Close the dialog once it has its answer or timed out, and act on the answer."""
        dialog = self.dialog
        steady = self.sessions.steady(now)
        if dialog is None or (dialog.answer is None and not dialog.expired(steady)):
            return
        self.dialog = None
        self.expression.interrupt_source(DIALOG_SOURCE, steady)
        sessions, session = self.sessions, self.sessions.session
        answered = dialog.answer is not None
        # counted unanswered here, before the answer acts (nothing below reads the count)
        sessions.note_interaction(dialog.channel or sessions.style(), answered, now)
        if dialog.kind is DialogKind.CONFIRM_CANCEL:
            self._close_confirm(dialog, now)
        elif dialog.kind is DialogKind.FEEDBACK and dialog.answer is not None:
            score = feedback_score(dialog.answer)
            if score is not None and session is not None:
                activity = dialog.context["activity"]
                user_id = session.user_id
                sessions.write(user_id, lambda p: p.record_feedback(user_id, activity, score, now))
        elif dialog.kind is DialogKind.GENERAL_QUESTION:
            question = self.question
            self.question = None
            if question is not None and dialog.answer is not None and session:
                sessions.record_answer(question, dialog.answer, now)

    def _close_confirm(self, dialog: Dialog, now: datetime) -> None:
        """The answer to "continue or stop?": stop cancels the activity (the user's own
        initiative), anything else or no answer resumes it."""
        runner = self.runner
        running = runner.current
        if running is None:
            return
        if dialog.answer is not None and dialog.answer in CONFIRM_STOP:
            self.sessions.note_initiative(True, now)
            runner.cancel(running, "confirm_cancel", now, f"the user said {dialog.answer!r}")
            self.sessions.record_activity(running, "cancelled", now)
        else:
            why = f"the user said {dialog.answer!r}" if dialog.answer else "no answer"
            runner.resume(running, "confirm_cancel", now, why)

    def end(self, now: datetime) -> None:
        """Close the open dialog without its answer and silence what it was saying."""
        self.dialog = None
        self.question = None
        self.held = None
        self.expression.interrupt_source(DIALOG_SOURCE, self.sessions.steady(now))

    def close_for_request(self, now: datetime) -> None:
        """The user asked for an activity (or a program asked to start or stop one)
        while a dialog is open: the request wins, the dialog closes at once, not counted
        as unanswered; a paused activity "continue or stop?" was about stays paused for
        the request to cancel."""
        if self.dialog is not None:
            self.end(now)

    # ------------------------------------------------------------------ a reminder in between

    def hold(self, now: datetime) -> None:
        """A reminder interrupts the open dialog: it falls silent and waits in
        :attr:`held` to be asked again when the reminder has been said."""
        dialog, question = self.dialog, self.question
        if dialog is None:
            return
        self.end(now)
        self.held = dialog, question

    def forget_held(self) -> None:
        """What a reminder interrupted does not come back: the held dialog is dropped."""
        self.held = None

    @property
    def held_dialog(self) -> Dialog | None:
        """The dialog a reminder interrupted, if any: it still takes an answer."""
        return self.held[0] if self.held is not None else None

    def ask_again(self, now: datetime) -> None:
        """After the reminder: the held dialog's answer given meanwhile is taken, else
        the question is asked again with its whole time to answer.

        Asked again rather than dropped: the user had not answered yet, and after a short
        reminder the question is still what the robot wants to know (a pause is history).
        """
        held, self.held = self.held, None
        if held is None:
            return
        dialog, self.question = held
        if dialog.answer is not None:
            self.dialog = dialog
            self.advance(now)
            return
        dialog.rearm(self.sessions.steady(now))
        self.open(dialog, now)
