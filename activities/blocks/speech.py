"""Speech and dialog: say a sentence, ask a question, offer the menu of activities.

The robot's voice (volume, rate) comes from the ``VoiceSettings`` rule; an answer is
taken by speech (whole words, digits read as numbers) or by a screen choice.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from datetime import datetime, timedelta
from typing import Any, ClassVar, Literal, cast

from pydantic import (
    Field,
)

from activities.blocks.base import Block
from activities.blocks.params import BlockParams, Text
from activities.containers import words
from activities.engine import Event, Runtime, Status, Wake
from activities.synonyms import match_activity
from dms.kernel.activity_names import USER_SELECTABLE, current
from dms.kernel.expression import Priority
from dms.kernel.messages import ScreenChoice, Speech, Touch
from dms.kernel.words import digits

VOLUMES = {"quiet": 40, "soft": 40, "normal": 60, "loud": 80, "very_loud": 95}


def voice_settings(rt: Runtime) -> dict[str, int]:
    """The ``VoiceSettings`` rule's ``volume`` (``volume:NN``, ``quiet``, ``normal``,
    ``loud``) and ``rate_wpm`` (``rate:WPM``), for the robot's speech; empty without it."""
    rules = rt.ctx.rules
    if rules is None:
        return {}
    result = rules.evaluate("VoiceSettings", rt.ctx.params())
    if result is None:
        return {}
    settings: dict[str, int] = {}
    for activation in result.activate:
        name = str(activation).strip().lower()
        if name in VOLUMES:
            settings.setdefault("volume", VOLUMES[name])
        elif match := re.fullmatch(r"volume[:=\s]*(\d{1,3})", name):
            settings.setdefault("volume", min(100, int(match.group(1))))
        elif match := re.fullmatch(r"rate[:=\s]*(\d{2,3})", name):
            settings.setdefault("rate_wpm", min(400, max(40, int(match.group(1)))))
    return settings


def speech_args(rt: Runtime, text: str, volume: float | None) -> dict[str, Any]:
    args: dict[str, Any] = {"text": text, **voice_settings(rt)}
    if volume is not None:
        args["volume"] = int(volume)
    return args


class SpeakParams(BlockParams):
    text: Text = Field(description="What to say; may use placeholders.")
    priority: Literal["normal", "high"] = Field(
        "normal", description="high: said before what else is queued."
    )
    volume: float | None = Field(
        None, description="0-100; by default the VoiceSettings rule decides."
    )


class Speak(Block[SpeakParams]):
    NAME = "speak"
    DOC = "Say a sentence; done when the robot has said it."
    PARAMS = SpeakParams

    def begin(self, now: datetime) -> None:
        self.handles = []
        priority = Priority.HIGH if self.args.priority == "high" else Priority.NORMAL
        args = speech_args(self.rt, self.args.text, self.args.volume)
        self.command("speech", "say", args, now, priority)


def match_answer(text: str, choices: Sequence[str]) -> str | None:
    """The choice ``text`` names (the longest one said as whole words), else None."""
    spoken = f" {digits(words(text))} "  # "six" answers "6"
    best: str | None = None
    for choice in choices:
        wanted = words(choice)
        if wanted.strip() and wanted in spoken and (best is None or len(choice) > len(best)):
            best = choice
    return best


class AskParams(BlockParams):
    question: Text = Field(description="What is asked (said, and shown with its choices).")
    choices: list[Text] = Field([], description="The answers taken; none: any answer.")
    correct: Text | None = Field(
        None, description="The right choice: the outcome is then correct or wrong."
    )
    branch: bool = Field(False, description="true: the outcome is the choice itself.")
    timeout_s: float = Field(12.0, description="Asked again after this long without answer.")
    attempts: int = Field(2, description="How many times it is asked at most.")
    key: str = Field("answer", description="Userdata key that receives the answer.")
    retry_text: Text = Field(
        "Sorry, I did not get that.", description="Said before asking again when misheard."
    )


class Ask(Block[AskParams]):
    NAME = "ask"
    DOC = (
        "Ask a question (said, and shown with its choices); take the answer by speech or "
        "screen; re-ask after a timeout, up to `attempts` times. With `correct`, the outcome "
        "says whether the answer was right; with `branch`, the outcome is the choice."
    )
    PARAMS: ClassVar[type[BlockParams]] = AskParams

    @classmethod
    def outcomes_for(cls, params: Mapping[str, Any]) -> tuple[str, ...]:
        choices = params.get("choices")
        if params.get("branch") is True and isinstance(choices, list):
            return (*[str(c) for c in choices], "no_answer")
        if params.get("correct") is not None:
            return ("correct", "wrong", "no_answer")
        return ("answered", "no_answer")

    def initialise(self, now: datetime) -> None:
        self.attempt = 0
        self.answer: str | None = None
        self.misheard = False
        super().initialise(now)

    def prompt(self) -> str:
        return self.args.question

    def choices(self) -> list[str]:
        return list(self.args.choices)

    def begin(self, now: datetime) -> None:
        self.withdraw(now)
        self.attempt += 1
        self.deadline: datetime | None = None
        text = self.prompt()
        if self.misheard:
            text = f"{self.args.retry_text} {text}"
            self.misheard = False
        if self.choices() and (
            self.rt.ctx.params().get("user", {}).get("interaction_style") == "screen"
        ):
            # the paper's Table 2: voice did not work for some users
            text = f"{text} Please answer on the screen."
        self.said = self.command("speech", "say", speech_args(self.rt, text, None), now)
        if self.choices():
            shown = {"text": self.prompt(), "choices": self.choices(), **self.screen_extra()}
            self.command("screen", "show", shown, now)

    def screen_extra(self) -> dict[str, Any]:
        """More for the screen beside the question and its choices (the menu's)."""
        return {}

    def on_pause(self, now: datetime) -> None:
        self.attempt -= 1  # the interrupted question is asked again, not counted twice
        super().on_pause(now)

    def interpret(self, event: Event) -> str | None:
        choices = self.choices()
        if isinstance(event, ScreenChoice):
            if not choices:
                return event.choice
            return next((c for c in choices if c.lower() == event.choice.strip().lower()), None)
        if isinstance(event, Speech):
            return match_answer(event.text, choices) if choices else event.text.strip() or None
        return None

    def on_event(self, event: Event) -> bool:
        if self.answer is not None or isinstance(event, Touch):
            return False
        answer = self.interpret(event)
        if answer is None:
            if isinstance(event, Speech) and match_activity(event.text) is not None:
                return False  # a request for another activity: the controller's
            self.misheard = True
            return True
        self.answer = answer
        return True

    def update(self, now: datetime) -> Status:
        error = self.command_error()
        if error is not None:
            return self.fail(error)
        if self.answer is not None:
            self.withdraw(now)
            return self.finish(self.answered(self.answer))
        if self.deadline is None and self.said.finished:
            self.deadline = now + timedelta(seconds=self.args.timeout_s)
        timed_out = self.deadline is not None and now >= self.deadline
        if self.misheard or timed_out:
            if self.attempt >= self.args.attempts:
                self.withdraw(now)
                return self.finish("no_answer")
            self.begin(now)
        return Status.RUNNING

    def wake(self, now: datetime) -> Wake | None:
        """It waits for its commands (the question said, a failure), for its deadline to
        ask again, or for an answer it takes (taking one, or mishearing, wakes it)."""
        waiting = self.waiting_on_commands() if self.updates_as(Ask) else None
        return None if waiting is None else waiting.until(self.deadline)

    def answered(self, answer: str) -> str:
        self.ud[self.args.key] = answer
        if self.args.branch:
            return answer
        correct = self.args.correct
        if correct is not None:
            return "correct" if answer.strip().lower() == correct.lower() else "wrong"
        return "answered"


class MenuParams(BlockParams):
    title: Text = Field("What would you like to do?", description="The question asked.")
    options: list[str] = Field(
        list(USER_SELECTABLE), description="The activities offered (by their names)."
    )
    timeout_s: float = Field(20.0, description="Asked again after this long without answer.")
    attempts: int = Field(2, description="How many times it is asked at most.")
    key: str = Field("choice", description="Userdata key that receives the choice.")
    retry_text: Text = Field(
        "Sorry, which one?", description="Said before asking again when misheard."
    )


class Menu(Ask):
    NAME = "menu"
    DOC = (
        "Show the user-selectable activities and take the choice (screen, or saying an "
        "activity or a synonym); the chosen activity becomes the result's redirect. "
        '"You choose" (or "surprise me"...) declines: the user leaves the choice '
        "to the robot."
    )
    OUTCOMES = ("chosen", "declined", "no_answer")
    PARAMS = MenuParams

    @classmethod
    def outcomes_for(cls, params: Mapping[str, Any]) -> tuple[str, ...]:
        return cls.OUTCOMES

    def bind_params(self) -> None:
        """The menu is an ask question made of the menu's parameters."""
        menu = cast(MenuParams, self.bound())
        # Not written: the activities in force now, declared ones included.
        options = menu.options if "options" in menu.model_fields_set else USER_SELECTABLE
        self.args = AskParams.model_construct(
            question=menu.title,
            choices=list(options),
            timeout_s=menu.timeout_s,
            attempts=menu.attempts,
            key=menu.key,
            retry_text=menu.retry_text,
        )

    def screen_extra(self) -> dict[str, Any]:
        """The menu names and pictures of the declared activities offered (none of the
        shipped, whose names are shown as they are)."""
        labels, pictures = {}, {}
        for name in self.choices():
            entry = current().entry(name)
            if entry is None or entry.shipped:
                continue
            labels[name] = entry.label or name
            if entry.picture:
                pictures[name] = entry.picture
        extra: dict[str, Any] = {"labels": labels} if labels else {}
        if pictures:
            extra["pictures"] = pictures
        return extra

    def interpret(self, event: Event) -> str | None:
        options = self.choices()
        if isinstance(event, ScreenChoice):
            text = event.choice.strip().lower()
            if text in options:
                return text
            named = match_activity(text)
        elif isinstance(event, Speech):
            text = event.text
            named = match_activity(text)
        else:
            return None
        if named is None and declines(text):
            return DECLINED
        return named if named in options else None

    def on_event(self, event: Event) -> bool:
        if self.answer is not None or isinstance(event, Touch):
            return False
        answer = self.interpret(event)
        if answer is None:
            self.misheard = isinstance(event, Speech)
            return self.misheard
        self.answer = answer
        return True

    def answered(self, answer: str) -> str:
        if answer == DECLINED:
            return "declined"
        self.ud[self.args.key] = answer
        self.rt.redirect = answer
        return "chosen"


DECLINED = "\x00declined"
"""The answer that leaves the choice to the robot (never an option's name)."""

_DECLINING = (
    "you choose",
    "you decide",
    "your choice",
    "surprise me",
    "you pick",
    "up to you",
    "whatever you like",
    "whatever you want",
    "i don't mind",
    "i don't know",
)


def declines(text: str) -> bool:
    """True if ``text`` leaves the choice to the robot ("you choose", "surprise me")."""
    folded = " ".join(text.lower().replace("’", "'").split())
    return any(phrase in folded for phrase in _DECLINING)
