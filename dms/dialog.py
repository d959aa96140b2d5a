"""Short spoken dialogs the controller holds itself, outside any activity.

Three of the paper's steps are questions put by the decision-making system, not by an
activity: "continue or stop?" after a touch on the right shoulder, "how much did you
like it?" after an activity (step 7) and general questions that fill the profile
(step 8). A :class:`Dialog` asks once, in the user's interaction style (voice or
screen, which the profile switches after repeated unanswered prompts: Table 2), takes
the first answer that arrives by speech or touch screen, and gives up after its timeout.

Its times are on the controller's steady clock (the wall time with its steps taken out,
:class:`~dms.kernel.clock.SteadyTime`): a wall clock set forward an hour while a question
waits does not end it unanswered.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from datetime import datetime, timedelta
from enum import StrEnum
from typing import Any

from dms.kernel.expression import ExpressionArbiter, Priority
from dms.kernel.words import digits

SOURCE = "dms"
"""The expression source of the controller's own dialogs."""


class DialogKind(StrEnum):
    """Why the controller is asking."""

    CONFIRM_CANCEL = "confirm_cancel"
    FEEDBACK = "feedback"
    GENERAL_QUESTION = "general_question"


@dataclass
class Dialog:
    """One question waiting for an answer."""

    kind: DialogKind
    question: str
    choices: tuple[str, ...]
    deadline: datetime
    """When it gives up (steady time, as every time here)."""
    context: dict[str, Any] = field(default_factory=dict)
    answer: str | None = None
    channel: str | None = None
    """"voice" or "screen": how the answer came."""
    asked: datetime | None = None
    """When the question was last put (by :meth:`ask`)."""

    def ask(self, expression: ExpressionArbiter, now: datetime, style: str = "voice") -> None:
        """Put the question in the user's interaction style (the paper's Table 2).

        ``voice``: the robot says the question and the choices it can take; ``screen``:
        it shows the choices and says to answer on the screen. The screen shows the
        choices in both, and an answer by either channel is taken.
        """
        self.asked = now
        spoken = self.question
        if self.choices and style == "screen":
            spoken = f"{self.question} Please answer on the screen."
        elif self.choices and not any(c.lower() in self.question.lower() for c in self.choices):
            spoken = f"{self.question} You can say {say_choices(self.choices)}."
        expression.request(SOURCE, "speech", "say", {"text": spoken}, now, priority=Priority.HIGH)
        if self.choices:
            expression.request(
                SOURCE,
                "screen",
                "show",
                {"text": self.question, "choices": list(self.choices)},
                now,
                priority=Priority.HIGH,
            )

    def offer(self, text: str, channel: str) -> bool:
        """Take ``text`` as the answer if it is one; True if taken."""
        if self.answer is not None:
            return False
        answer = self.answer_in(text)
        if answer is None:
            return False
        self.answer, self.channel = answer, channel
        return True

    def answer_in(self, text: str) -> str | None:
        """The answer ``text`` gives (one of the choices, or any words if there are none)."""
        if self.kind is DialogKind.FEEDBACK:
            text = normalize_feedback(text)
        if self.choices:
            return match_choice(text, self.choices)
        return text.strip() or None

    def expired(self, now: datetime) -> bool:
        return self.answer is None and now >= self.deadline

    def rearm(self, now: datetime) -> None:
        """Give the question its whole time again from ``now``, before asking it again
        after an interruption (a reminder spoken in between)."""
        if self.asked is not None:
            self.deadline = now + (self.deadline - self.asked)


def say_choices(choices: tuple[str, ...]) -> str:
    """``"a, b or c"``: the choices as the robot reads them out."""
    return choices[0] if len(choices) == 1 else f"{', '.join(choices[:-1])} or {choices[-1]}"


def match_choice(text: str, choices: tuple[str, ...]) -> str | None:
    """The choice ``text`` names, as a whole word or the whole text, case-insensitive."""
    spoken = text.strip().lower()
    for choice in choices:
        if spoken == choice.lower():
            return choice
    words = set(re.findall(r"[\w']+", spoken))
    for choice in choices:
        if choice.lower() in words:
            return choice
    return None


CONFIRM_CHOICES = ("stop", "continue", "yes", "no")
CONFIRM_STOP = frozenset({"stop", "yes"})
"""Answers to "Do you want to stop?" that stop; "continue" and "no" go on."""

FEEDBACK_CHOICES = ("1", "2", "3", "4", "5")
FEEDBACK_WORDS = {
    "1": 0.0,
    "2": 0.25,
    "3": 0.5,
    "4": 0.75,
    "5": 1.0,
}


def confirm_dialog(activity: str, now: datetime, timeout_s: float) -> Dialog:
    return Dialog(
        DialogKind.CONFIRM_CANCEL,
        f"Do you want to stop the {activity.replace('_', ' ')}? Say stop or continue.",
        CONFIRM_CHOICES,
        now + timedelta(seconds=timeout_s),
        {"activity": activity},
    )


def feedback_dialog(activity: str, now: datetime, timeout_s: float) -> Dialog:
    return Dialog(
        DialogKind.FEEDBACK,
        f"How much did you like the {activity.replace('_', ' ')}, from one to five?",
        FEEDBACK_CHOICES,
        now + timedelta(seconds=timeout_s),
        {"activity": activity},
    )


def feedback_score(answer: str) -> float | None:
    """A 0..1 score from a 1-5 answer (digit or word)."""
    return FEEDBACK_WORDS.get(digits(answer))


def normalize_feedback(text: str) -> str:
    """Turn number words into digits so "four" matches the choice "4"."""
    return digits(text)
