"""A simulated user: a persona reacting to what the robot says, shows and decides.

The user lives on whatever clock drives it: every method takes ``now``. It is told
of each robot command (:meth:`SimulatedUser.on_command`: speech ``say``, screen
``show`` with choices, ...) and each decision (:meth:`on_decision`), and answers with
inputs that fall due later (:meth:`due`): an answer by voice or on the screen after a
delay (sometimes misrecognized, sometimes never given), a menu choice according to
its hidden preferences, an activity asked for by name, a touch on the right shoulder
and "stop" in an activity it dislikes. :meth:`perception` is what the perception
module would publish about it, with the face's position from the user's :class:`sim.seat.Seat`
(they lean and move their chair now and then). The same object drives the in-process simulation
(``sim.harness``) and the Zenoh visitor (``sim.visitor``).
"""

from __future__ import annotations

import heapq
import itertools
import random
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from datetime import datetime, timedelta

from pydantic import BaseModel

from dms.kernel import keys
from dms.kernel.activity_names import ACTIVITIES, ENTERTAINMENT_ACTIVITIES
from dms.kernel.messages import (
    Decision,
    Pose,
    RobotCommand,
    ScreenChoice,
    Speech,
    Touch,
    UserPerception,
    Vector3,
)
from sim.persona import Persona, Span
from sim.seat import Position, Seat

Output = tuple[str, BaseModel]
"""An input for the daemon: (key relative to the robot, message)."""

CONFIRM_WORDS = frozenset({"stop", "continue", "yes", "no"})
FEEDBACK_WORDS = ("1", "2", "3", "4", "5")
REQUEST_PHRASES = ("let's do the {}", "I would like the {}", "can we do the {}, please?")
INITIATIVE_QUESTION = "how often should i start"
"""Words of the general question on initiative (the robot asks how often it should start)."""
DECLINE_PHRASE = "you choose"
"""What a user says or taps to leave the menu's choice to the robot."""


@dataclass
class UserStats:
    """What the user did: the study's failure counts come from here."""

    questions_heard: int = 0
    answers: int = 0
    voice_answers: int = 0
    screen_answers: int = 0
    misrecognized: int = 0
    """Utterances sent garbled (the speech recognizer got them wrong)."""
    unanswered: int = 0
    touches: int = 0
    requests_by_name: int = 0
    menu_choices: int = 0
    menu_declines: int = 0
    rhetorical: int = 0
    """Spoken questions inside an activity, with no choices, not answered (a joke's setup)."""


@dataclass
class _Question:
    text: str
    asked: datetime
    choices: tuple[str, ...] = ()
    answered: bool = False
    retried: bool = False
    not_before: datetime | None = None
    """The user is still looking at the choices (a menu, a rating) until then."""
    said: str | None = None
    """What the user answers, once chosen: misheard, they say it again rather than choose
    anew (a "you choose" stays one: a second draw would decline less than the persona)."""


@dataclass(order=True)
class _Pending:
    due: datetime
    order: int
    action: Callable[[datetime], list[Output]] = field(compare=False)


def _draw(rng: random.Random, span: Span) -> float:
    return span.min if span.max <= span.min else rng.uniform(span.min, span.max)


class SimulatedUser:
    """One persona in front of (or away from) the robot."""

    def __init__(self, persona: Persona, rng: random.Random, user_id: str | None = None) -> None:
        self.persona = persona
        self.user_id = user_id or persona.id
        self.rng = rng
        self.stats = UserStats()
        self.present = False
        self.ready = False
        self.activity: str | None = None
        """The activity the user believes runs (from the robot's decisions)."""
        self.last_activity: str | None = None
        self.done: set[str] = set()
        """Entertainment activities started during this visit."""
        self._activity_serial = 0
        self._wants_stop: str | None = None
        self.seat: Seat | None = None
        """Where the face is; made when the user arrives (its draws are its own)."""
        self._perceived: (
            tuple[tuple[bool, bool, str | None, Position | None], UserPerception] | None
        ) = None
        """The last perception and what it was made of (presence, readiness, activity,
        face): the same frozen message again while that holds, not one built every tick."""
        self._question: _Question | None = None
        self._queue: list[_Pending] = []
        self._order = itertools.count()
        self.touches_left = persona.patience.max_touches

    # ------------------------------------------------------------ presence

    def arrive(self, now: datetime) -> None:
        """Sit down in front of the robot; ready to interact after a short while."""
        self.present = True
        self.ready = False
        self.done = set()
        if self.seat is None:
            self.seat = Seat(now, f"{self.user_id}:seat")
        else:
            self.seat.sit(now)  # back in the chair: the moves while away never happened
        self._schedule(
            now + timedelta(seconds=_draw(self.rng, self.persona.arrive_after_s)), self._sit
        )

    def _sit(self, now: datetime) -> list[Output]:
        if self.present:
            self.ready = True
            return [(keys.PERCEPTION_USER, self.perception(now))]
        return []

    def leave(self, now: datetime) -> None:
        """Get up and go: every pending answer is forgotten."""
        self.present = self.ready = False
        self._queue.clear()
        self._question = None
        self.activity = None
        self._wants_stop = None

    def perception(self, now: datetime | None = None) -> UserPerception:
        """What a perception module publishes about this user now (with ``now``: where
        their face is, too)."""
        face = None
        if self.present and self.seat is not None and now is not None:
            face = self.seat.face(now)
        state = (self.present, self.ready, self.activity, face)
        if self._perceived is not None and self._perceived[0] == state:
            return self._perceived[1]
        if not self.present:
            message = UserPerception(present=False, user_id=None, ready=False, engagement=None)
        else:
            engagement = self.persona.liking(self.activity) if self.activity else 0.7
            message = UserPerception(
                present=True,
                user_id=self.user_id,
                ready=self.ready,
                engagement=round(engagement, 2),
                face=None
                if face is None
                else Pose(position=Vector3(x=face[0], y=face[1], z=face[2])),
            )
        self._perceived = (state, message)
        return message

    # ------------------------------------------------------------ the queue

    def _schedule(self, when: datetime, action: Callable[[datetime], list[Output]]) -> None:
        heapq.heappush(self._queue, _Pending(when, next(self._order), action))

    def next_due(self) -> datetime | None:
        """When the user will next do something by itself, if it will."""
        return self._queue[0].due if self._queue else None

    def due(self, now: datetime) -> list[Output]:
        """Inputs the user produces up to ``now``, in order."""
        out: list[Output] = []
        while self._queue and self._queue[0].due <= now:
            pending = heapq.heappop(self._queue)
            if self.present:
                out.extend(pending.action(now))
        return out

    # ------------------------------------------------------------ what the robot does

    def on_command(self, command: RobotCommand, now: datetime) -> None:
        """Hear and see one robot command."""
        if not self.present or not self.ready:
            return
        question = self._question
        pending = question is not None and not question.answered
        if command.channel == "speech" and command.action == "say":
            text = str(command.args.get("text", ""))
            if "?" in text:
                if pending and question is not None and question.choices:
                    return  # the choices are on the screen already: the same question
                self._ask(text, (), now)
        elif command.channel == "screen" and command.action in ("show", "menu"):
            choices = _choices(command.args.get("choices"))
            if choices:
                if pending and question is not None and not question.choices:
                    # The screen shows the choices of what was just said (the channels
                    # are served apart, so they need not arrive at the same instant).
                    question.choices = choices
                    self._consider(question)
                    return
                text = str(command.args.get("text", command.args.get("title", "")))
                self._ask(text, choices, now)

    def _ask(self, text: str, choices: tuple[str, ...], now: datetime) -> None:
        question = self._question = _Question(text, now, choices)
        self.stats.questions_heard += 1
        delay = _draw(self.rng, self.persona.speech.answer_delay_s)
        self._schedule(now + timedelta(seconds=delay), lambda t: self._answer(question, t))
        self._consider(question)

    def _consider(self, question: _Question) -> None:
        """Choices that take longer than an answer: a menu to look through, a rating."""
        speech = self.persona.speech
        span = None
        if question.choices and set(question.choices) <= set(FEEDBACK_WORDS):
            span = speech.rating_delay_s
        elif any(_choice_activity(choice) is not None for choice in question.choices):
            span = speech.menu_delay_s
        if span is not None:
            question.not_before = question.asked + timedelta(seconds=_draw(self.rng, span))

    def on_decision(self, decision: Decision, now: datetime) -> None:
        """Follow what the robot decided: which activity runs now."""
        if not self.present:
            return
        name = decision.activity
        if decision.action in ("start", "resume") and name is not None:
            if decision.action == "start" or name != self.activity:
                self._started(name, now)
        elif decision.action in ("complete", "cancel", "fail") and name == self.activity:
            self.activity = None
            self._wants_stop = None
            if decision.action == "complete" and name in ENTERTAINMENT_ACTIVITIES:
                self.last_activity = name
                self._maybe_ask_by_name(now)

    def _started(self, name: str, now: datetime) -> None:
        self.activity = name
        self._activity_serial += 1
        self._wants_stop = None
        if name not in ENTERTAINMENT_ACTIVITIES:
            return
        self.done.add(name)
        patience = self.persona.patience
        chance = self.persona.stop_chance(name)
        if chance >= 1.0 or (chance > 0.0 and self.rng.random() < chance):
            serial = self._activity_serial
            wait = _draw(self.rng, patience.stop_after_s)
            self._schedule(now + timedelta(seconds=wait), lambda t: self._lose_patience(serial, t))

    # ------------------------------------------------------------ what the user does

    def _lose_patience(self, serial: int, now: datetime) -> list[Output]:
        if serial != self._activity_serial or self.activity is None:
            return []
        if self.touches_left is not None and self.touches_left <= 0:
            return []
        if self.touches_left is not None:
            self.touches_left -= 1
        self._wants_stop = self.activity
        self.stats.touches += 1
        return [(keys.PERCEPTION_TOUCH, Touch(part="right_shoulder", kind="tap"))]

    def _maybe_ask_by_name(self, now: datetime) -> None:
        if self.rng.random() >= self.persona.ask_by_name_rate:
            return
        delay = _draw(self.rng, self.persona.speech.answer_delay_s)
        self._schedule(now + timedelta(seconds=delay), self._ask_by_name)

    def _ask_by_name(self, now: datetime) -> list[Output]:
        question = self._question
        if question is not None and not question.answered and (now - question.asked).seconds < 30:
            return []  # the robot is asking something: answer that instead
        options = [name for name in self.persona.favourites()[:3] if name != self.last_activity]
        wanted = self.rng.choice(options)
        phrase = self.rng.choice(REQUEST_PHRASES).format(wanted)
        self.stats.requests_by_name += 1
        return self._say(phrase, now, retry=None)

    def say(self, text: str, now: datetime) -> list[Output]:
        """Say ``text`` (through the recognizer: it may come out garbled)."""
        return self._say(text, now, retry=None)

    def _answer(self, question: _Question, now: datetime) -> list[Output]:
        if question is not self._question or question.answered:
            return []
        if question.not_before is not None and now < question.not_before:
            when = question.not_before
            self._schedule(when, lambda t: self._answer(question, t))
            return []
        if not question.choices and self.activity in ENTERTAINMENT_ACTIVITIES:
            # A spoken question with nothing to choose inside an entertainment activity
            # (a joke's setup, "do you know any other sayings?"): the robot goes on by
            # itself; those activities take answers with choices on the screen.
            question.answered = True
            self.stats.rhetorical += 1
            return []
        speech = self.persona.speech
        if not question.retried and self.rng.random() < speech.no_answer_rate:
            question.answered = True
            self.stats.unanswered += 1
            return []
        if question.said is None:
            question.said = self._choose_answer(question)
        text = question.said
        if question.choices and self.rng.random() < speech.screen_rate:
            question.answered = True
            self.stats.answers += 1
            self.stats.screen_answers += 1
            if _is_activity(text):
                self.stats.menu_choices += 1
            return [(keys.PERCEPTION_SCREEN, ScreenChoice(choice=text))]
        return self._say(text, now, retry=question)

    def _say(self, text: str, now: datetime, retry: _Question | None) -> list[Output]:
        speech = self.persona.speech
        if self.rng.random() < speech.error_rate:
            self.stats.misrecognized += 1
            if retry is not None and not retry.retried:
                # Not understood: the user tries once more, a little later.
                retry.retried = True
                delay = _draw(self.rng, speech.answer_delay_s)
                self._schedule(now + timedelta(seconds=delay), lambda t: self._answer(retry, t))
            garbled = _garble(text, self.rng)
            return [(keys.PERCEPTION_SPEECH, Speech(text=garbled, confidence=0.3))]
        if retry is not None:
            retry.answered = True
            self.stats.answers += 1
            self.stats.voice_answers += 1
            if _is_activity(text):
                self.stats.menu_choices += 1
        confidence = round(self.rng.uniform(0.75, 0.98), 2)
        return [(keys.PERCEPTION_SPEECH, Speech(text=text, confidence=confidence))]

    def _choose_answer(self, question: _Question) -> str:
        choices = question.choices
        asked = question.text.lower()
        for phrase, answer in self.persona.answers.items():
            if phrase.lower() in asked:
                return answer
        if INITIATIVE_QUESTION in asked and choices:
            # the question on initiative: answered as the persona's proactivity has it,
            # not at random (a low one wants the robot to start often)
            wanted = self.persona.initiative_answer()
            return next((c for c in choices if c.lower() == wanted), self._pick(choices))
        lowered = {choice.lower() for choice in choices}
        if lowered & {"stop", "continue"} and lowered <= CONFIRM_WORDS:
            stop = self._wants_stop is not None and self._wants_stop == self.activity
            if stop and self.rng.random() < self.persona.patience.continue_rate:
                stop = False
            wanted = "stop" if stop else "continue"
            return next((c for c in choices if c.lower() == wanted), choices[0])
        if choices and set(choices) <= set(FEEDBACK_WORDS):
            return self._rating(question)
        if choices:
            told = self._feature_answer(question.text, choices)
            return told if told is not None else self._pick(choices)
        return self._open_answer(question.text)

    def _rating(self, question: _Question) -> str:
        name = _named_activity(question.text) or self.last_activity
        liking = self.persona.liking(name) if name else 0.5
        score = min(5, max(1, round(1 + 4 * liking + self.rng.gauss(0.0, 0.4))))
        return str(score)

    def _pick(self, choices: Sequence[str]) -> str:
        """A menu: the best-liked activity among them not done yet this visit (people
        try different ones: the paper's participants did 4-6 different activities), or
        "you choose" (as often as the persona leaves the initiative to the robot); else
        (a quiz, a yes/no question) any choice."""
        named = [(name, choice) for choice in choices if (name := _choice_activity(choice))]
        # They came for the entertainment activities (the paper's menus, its Fig. 5).
        named = [pair for pair in named if pair[0] in ENTERTAINMENT_ACTIVITIES] or named
        fresh = [(name, choice) for name, choice in named if name not in self.done]
        scored = [
            (self.persona.liking(name) + self.rng.uniform(0.0, 0.25), choice)
            for name, choice in (fresh or named)
        ]
        if scored:
            decline = self.persona.declines_menu()
            if decline > 0.0 and self.rng.random() < decline:
                self.stats.menu_declines += 1
                return DECLINE_PHRASE
            return max(scored)[1]
        return self.rng.choice(list(choices))

    def _feature_answer(self, text: str, choices: Sequence[str]) -> str | None:
        """A yes/no question about one of the persona's true/false features ("Do you
        live alone?" for ``lives_alone``): the truth, among ``choices``."""
        lowered = {choice.lower(): choice for choice in choices}
        if not {"yes", "no"} <= set(lowered):
            return None
        for name, value in self.persona.features.items():
            if isinstance(value, bool) and _asks_about(name, text):
                return lowered["yes" if value else "no"]
        return None

    def _open_answer(self, text: str) -> str:
        lowered = text.lower()
        for name, value in self.persona.features.items():
            if re.search(rf"\b{re.escape(name.replace('_', ' '))}\b", lowered):
                return str(value)
        if "how are you" in lowered:
            return "fine, thank you"
        if "old" in lowered and "age" in self.persona.features:
            return str(self.persona.features["age"])
        return self.rng.choice(("yes", "I think so", "maybe", "no"))


def _asks_about(feature: str, text: str) -> bool:
    """Whether ``text`` asks about ``feature``: every word of its name, or the word's
    stem (``lives`` is asked as "live"), appears in it."""
    lowered = text.lower()
    return all(re.search(rf"\b{re.escape(word[:4])}", lowered) for word in feature.split("_"))


def _choices(raw: object) -> tuple[str, ...]:
    if isinstance(raw, list | tuple):
        out = []
        for item in raw:
            if isinstance(item, str):
                out.append(item)
            elif isinstance(item, dict):
                label = item.get("id", item.get("value", item.get("label")))
                if label is not None:
                    out.append(str(label))
        return tuple(out)
    return ()


def _choice_activity(choice: str) -> str | None:
    """The activity a menu choice names (its name, or a synonym such as "music")."""
    name = choice.strip().lower().replace(" ", "_")
    if name in ACTIVITIES:
        return name
    from activities.synonyms import match_activity

    return match_activity(choice)


def _is_activity(text: str) -> bool:
    return _choice_activity(text) is not None


def _named_activity(text: str) -> str | None:
    lowered = text.lower().replace(" ", "_")
    return next((name for name in ACTIVITIES if name in lowered), None)


def _garble(text: str, rng: random.Random) -> str:
    """What a speech recognizer makes of an utterance it got wrong."""
    syllables = ("ba", "ro", "mi", "ta", "ne", "lu", "so", "ke")
    return " ".join(
        "".join(rng.choice(syllables) for _ in range(rng.randint(1, 3)))
        for _ in range(max(1, len(text.split())))
    )
