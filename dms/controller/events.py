"""Urgent inputs, handled first in a tick: requests, touches, speech, screen choices.

An answer goes to the open dialog, else to the running activity; a request for an
activity by name (from an app, by voice or on the screen) is put in the
:class:`~dms.controller.requests.Requests` queue, which this tick's decision point (the
cancel reasons or the choice) takes from.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from datetime import datetime

from activities.synonyms import bare_activity, match_activity, requests_activity
from dms.config import ControllerSettings
from dms.controller.deps import ControllerDeps, Counters
from dms.controller.dialogs import Dialogs
from dms.controller.requests import Asked, Requests
from dms.controller.running import Runner, Running
from dms.controller.sessions import Sessions
from dms.dialog import Dialog, DialogKind, confirm_dialog
from dms.faults import FaultBarrier
from dms.inputs import InputSnapshot
from dms.kernel import keys
from dms.kernel.activity_names import ACTIVITIES
from dms.kernel.messages import Request, ScreenChoice, Speech, Touch

log = logging.getLogger(__name__)


class Events:
    """Hands each urgent input of a tick to whom it concerns."""

    def __init__(
        self,
        deps: ControllerDeps,
        settings: ControllerSettings,
        counters: Counters,
        barrier: FaultBarrier,
        sessions: Sessions,
        runner: Runner,
        dialogs: Dialogs,
        requests: Requests,
        reload_rules: Callable[[], None],
    ) -> None:
        self.deps = deps
        self.settings = settings
        self.counters = counters
        self.barrier = barrier
        self.sessions = sessions
        self.runner = runner
        self.dialogs = dialogs
        self.requests = requests
        self.reload_rules = reload_rules
        self.touches: list[tuple[str, str]] = []
        """(part, kind) of this tick's touches, for the motivation."""

    def handle(self, snapshot: InputSnapshot, now: datetime) -> None:
        """Handle this tick's events in order, each under the fault barrier."""
        self.touches = []
        for event in snapshot.events:
            self.barrier.run(
                f"event/{event.key}", event.message, self.handle_one, event.message, now
            )

    def handle_one(self, message: object, now: datetime) -> None:
        """One urgent input: a request, a touch, an utterance or a screen choice."""
        if isinstance(message, Request):
            self.on_request(message, now)
        elif isinstance(message, Touch):
            self.touches.append((message.part, message.kind))
            self.on_touch(message, now)
        elif isinstance(message, Speech):
            if message.confidence < self.settings.min_speech_confidence:
                log.info("not understood (confidence %.2f): %r", message.confidence, message.text)
                self.counters.count_misheard()
                return
            self.on_answer(message.text, "voice", message, now)
        elif isinstance(message, ScreenChoice):
            self.on_answer(message.choice, "screen", message, now)

    def on_request(self, request: Request, now: datetime) -> None:
        """A request from another program: served in this tick, or answered with why not."""
        by = request.by or "request"
        own = self.sessions.is_the_user(request.by)
        runner, dialogs = self.runner, self.dialogs
        running = runner.current
        if request.action == "reload_rules":
            self.reload_rules()
        elif request.action == "start" and request.activity is not None:
            if self._continues(request.activity, now):
                return  # the activity "continue or stop?" is about: go on with it
            dialogs.close_for_request(now)
            self.requests.put(Asked(request.activity, "user", f"requested by {by}", own))
            if own:
                self.sessions.note_initiative(True, now)
        elif request.action == "start":
            self._refuse(request, "start needs an activity")
        elif request.action == "cancel" and self._withdraws(request, running):
            pass  # asked for earlier in this tick and not started yet: it never starts
        elif request.action == "cancel" and running is not None:
            if request.activity in (None, running.name):
                dialogs.close_for_request(now)
                self.requests.put(Asked("", "user", f"cancel requested by {by}", own))
            else:
                self._refuse(request, f"{request.activity} does not run ({running.name} does)")
        elif request.action == "pause" and running is not None and not running.paused:
            runner.pause(running, "user_request", now, f"requested by {by}")
        elif request.action == "resume" and running is not None and running.paused:
            dialog = dialogs.dialog
            if dialog is not None and dialog.kind is DialogKind.CONFIRM_CANCEL:
                dialog.offer("continue", "request")  # the answer to "continue or stop?"
                dialogs.advance(now)
            else:
                runner.resume(running, "user_request", now, f"requested by {by}")
        elif running is None:
            self._refuse(request, f"nothing to {request.action}: no activity runs")
        else:
            state = "paused" if running.paused else "running"
            self._refuse(request, f"nothing to {request.action}: {running.name} is {state}")

    def _withdraws(self, request: Request, running: Running | None) -> bool:
        """Drop a start of the cancelled activity asked for earlier in this tick; True if
        that was all the cancel had to do (False when the activity also runs: it is
        cancelled too)."""
        withdrawn = self.requests.withdraw(request.activity)
        return withdrawn and (running is None or running.name != request.activity)

    def _continues(self, activity: str, now: datetime) -> bool:
        """A start of the activity that "continue or stop?" is about answers "continue";
        True if it did."""
        dialog = self.dialogs.dialog
        if (
            dialog is None
            or dialog.kind is not DialogKind.CONFIRM_CANCEL
            or dialog.context.get("activity") != activity
        ):
            return False
        dialog.offer("continue", "request")
        self.dialogs.advance(now)
        return True

    def _refuse(self, request: Request, why: str) -> None:
        """A request that cannot be served: said on ``dms/errors``, never dropped silently."""
        who = request.by or "request"
        self.deps.report_error(keys.REQUEST, f"{request.action} by {who}: {why}")

    def on_touch(self, touch: Touch, now: datetime) -> None:
        """The right shoulder during an activity the user has: pause it and ask
        "continue or stop?" (one that cannot be paused is stopped: nothing is left to
        ask about). Any other touch goes to the activity."""
        running = self.runner.current
        if (
            touch.part == "right_shoulder"
            and running is not None
            and self.dialogs.dialog is None
            and running.chosen_by != "motivation"
            and not running.paused
            and running.name != "notification"
        ):
            if not self.runner.pause(running, "confirm_cancel", now, "right shoulder touched"):
                return
            steady = self.sessions.steady(now)
            self.dialogs.open(
                confirm_dialog(running.name, steady, self.settings.confirm_timeout_s), now
            )
            return
        self.runner.deliver(touch)

    def on_answer(
        self, text: str, channel: str, event: Speech | ScreenChoice, now: datetime
    ) -> None:
        """Words or a screen choice: the open dialog's answer (or, while a reminder is
        said, the answer to the question it interrupted), unless they ask for an activity
        instead; else the running activity's input; else maybe a request."""
        wanted = match_activity(text)
        dialogs = self.dialogs
        dialog = dialogs.dialog or dialogs.held_dialog  # held: a reminder is being said
        if dialog is not None and not self._asks_instead(dialog, wanted, text, channel):
            if dialog.offer(text, channel) and dialog is dialogs.dialog:
                dialogs.advance(now)
            return
        if dialogs.dialog is not None:
            dialogs.close_for_request(now)
        elif self.runner.take_words(event, self.sessions.steady(now)):
            return
        running = self.runner.current
        if (
            wanted is not None
            and wanted in ACTIVITIES
            and (running is None or wanted != running.name)
        ):
            detail = f"asked by {channel}: {text[:60]!r}"
            self.requests.put(Asked(wanted, "user", detail, own=True))
            self.sessions.note_initiative(True, now)

    @staticmethod
    def _asks_instead(dialog: Dialog, wanted: str | None, text: str, channel: str) -> bool:
        """Whether words or a screen choice given while ``dialog`` is open ask for the
        activity ``wanted`` rather than answer: the user may ask for an activity during
        any question, unless the question offers that activity, or asks whether to stop
        it ("continue or stop?" about the bingo: "bingo" is no request).

        A screen choice of an activity is a request (a question's own choices aside, the
        screen offers activities); words are one if they sound like one ("let's play
        bingo"), or if the question has choices and they answer none of them, or if the
        question asks for a name and they are nothing but an activity's name or synonym
        ("bingo" to "What is your name?": no one is called Bingo by a robot's mistake).
        """
        if wanted is None:
            return False
        if dialog.context.get("field") == "name" and bare_activity(text) == wanted:
            return True
        if dialog.kind is DialogKind.CONFIRM_CANCEL and wanted == dialog.context.get("activity"):
            return False
        if any(match_activity(choice) == wanted for choice in dialog.choices):
            return False
        if channel == "screen" or requests_activity(text):
            return True
        return bool(dialog.choices) and dialog.answer_in(text) is None
