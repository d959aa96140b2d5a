"""General questions (step 8) that fill the profile's missing fields.

Each :class:`Question` names the field its answer fills; :meth:`QuestionBank.parse`
turns a spoken or tapped answer into values for that field (None when it did not
understand), and :meth:`QuestionBank.next_question` picks one whose field is still
empty: the name and the question on initiative first (so that a new user's first
choice already follows their answer), then the fields that help the preference
prediction.
"""

from __future__ import annotations

import random
import re
from collections.abc import Callable, Collection
from dataclasses import dataclass
from functools import cache
from typing import Any

from memory.profile import Profile

YES = frozenset({"yes", "yeah", "yep", "sure", "i do", "of course", "right", "true", "si", "sí"})
NO = frozenset({"no", "nope", "not really", "i don't", "i do not", "false"})

NUMBER_WORDS = {
    "twenty": 20,
    "thirty": 30,
    "forty": 40,
    "fifty": 50,
    "sixty": 60,
    "seventy": 70,
    "eighty": 80,
    "ninety": 90,
    "hundred": 100,
}
UNITS = {
    "one": 1,
    "two": 2,
    "three": 3,
    "four": 4,
    "five": 5,
    "six": 6,
    "seven": 7,
    "eight": 8,
    "nine": 9,
}


@dataclass(frozen=True, slots=True)
class Question:
    """One general question: what to say, the choices to show (if any), the field filled."""

    id: str
    text: str
    choices: tuple[str, ...] | None
    field: str


Parser = Callable[[str], Any]


def _clean(text: str) -> str:
    return re.sub(r"\s+", " ", text.strip().strip(".!?¡¿")).strip()


def _words(text: str) -> str:
    return " " + re.sub(r"[^a-záéíóúñü0-9' ]", " ", text.lower()) + " "


def parse_yes_no(text: str) -> bool | None:
    """True for yes, False for no, None otherwise."""
    lowered = _clean(text).lower()
    if lowered in YES or lowered.startswith(("yes ", "yes,")):
        return True
    if lowered in NO or lowered.startswith(("no ", "no,")):
        return False
    return None


def parse_age(text: str) -> int | None:
    """An age from "74", "I am 74 years old" or "seventy four"."""
    digits = re.findall(r"\d+", text)
    if digits:
        value = int(digits[0])
        return value if 0 < value <= 120 else None
    total = 0
    for word in _words(text).split():
        total += NUMBER_WORDS.get(word, 0) + UNITS.get(word, 0)
    return total if 0 < total <= 120 else None


def parse_sex(text: str) -> str | None:
    """``female``, ``male`` or ``other`` from the usual words."""
    words = _words(text)
    if any(f" {w} " in words for w in ("female", "woman", "girl", "lady", "mujer")):
        return "female"
    if any(f" {w} " in words for w in ("male", "man", "boy", "gentleman", "hombre")):
        return "male"
    if any(f" {w} " in words for w in ("other", "non-binary", "nonbinary")):
        return "other"
    return None


def parse_name(text: str) -> str | None:
    """A name from "Alice" or "my name is Alice" / "I'm Alice" / "call me Alice"."""
    cleaned = _clean(text)
    match = re.search(r"(?:my name is|i am|i'm|call me|it's|it is)\s+(.+)", cleaned, re.I)
    name = _clean(match.group(1) if match else cleaned)
    if not name or len(name) > 60 or any(ch.isdigit() for ch in name) or len(name.split()) > 4:
        return None
    return name if name[0].isupper() else name.title()


LANGUAGES = (
    "english",
    "spanish",
    "french",
    "german",
    "italian",
    "portuguese",
    "catalan",
    "basque",
    "galician",
    "greek",
    "dutch",
    "chinese",
    "arabic",
    "russian",
)


def parse_language(text: str) -> str | None:
    """A known language name, in English."""
    words = _words(text)
    for language in LANGUAGES:
        if f" {language} " in words:
            return language
    return None


def parse_hearing(text: str) -> bool | None:
    """Whether the user hears the robot well (True) or has trouble (False)."""
    words = _words(text)
    if any(
        w in words
        for w in (
            " not well ",
            " badly ",
            " bad ",
            " hard ",
            " poor",
            " deaf ",
            " trouble ",
            " louder ",
            " not really ",
        )
    ):
        return False
    if any(w in words for w in (" well ", " fine ", " good ", " perfectly ", " clearly ")):
        return True
    return parse_yes_no(text)


def parse_room(text: str) -> str | None:
    """A room name: "the living room" -> "living room"."""
    cleaned = re.sub(r"^(?:my |the |in the |i like the )", "", _clean(text).lower())
    return cleaned if 0 < len(cleaned) <= 60 else None


def parse_free_text(text: str) -> str | None:
    """Any short non-empty answer, as said."""
    cleaned = _clean(text)
    if not cleaned or len(cleaned) > 100 or parse_yes_no(cleaned) is not None:
        return None
    if cleaned.lower() in {"maybe", "i think so", "i don't know", "dont know", "no idea"}:
        return None
    return cleaned.lower()


def _choice_parser(*choices: str) -> Parser:
    def parse(text: str) -> str | None:
        words = _words(text)
        for choice in choices:
            if f" {choice} " in words:
                return choice
        return None

    return parse


@dataclass(frozen=True, slots=True)
class _Entry:
    question: Question
    parse: Parser
    priority: int


class QuestionBank:
    """The general questions, the fields they fill and how their answers are parsed."""

    def __init__(self, entries: Collection[_Entry]) -> None:
        self._entries = {entry.question.id: entry for entry in entries}

    @classmethod
    @cache
    def default(cls) -> QuestionBank:
        """The built-in bank: the name, then the question on initiative (it seeds the
        proactivity estimate, which sets the mode of the user's very first choice: the
        paper's step 6 reads it before every choice), then the features the preference
        predictor uses, then the rest."""

        def entry(
            qid: str,
            text: str,
            field: str,
            parse: Parser,
            priority: int,
            choices: tuple[str, ...] | None = None,
        ) -> _Entry:
            return _Entry(Question(qid, text, choices, field), parse, priority)

        return cls(
            [
                entry("name", "What is your name?", "name", parse_name, 0),
                entry(
                    "robot_initiative_frequency",
                    "How often should I start a conversation: low, moderate or high?",
                    "robot_initiative_frequency",
                    _choice_parser("low", "moderate", "high"),
                    1,
                    ("low", "moderate", "high"),
                ),
                entry("age", "How old are you?", "age", parse_age, 2),
                entry("sex", "What is your gender?", "sex", parse_sex, 2),
                entry("occupation", "What was your occupation?", "occupation", parse_free_text, 3),
                entry(
                    "education", "What education did you finish?", "education", parse_free_text, 3
                ),
                entry("hobbies", "What are your hobbies?", "hobbies", parse_free_text, 3),
                entry(
                    "lives_alone",
                    "Do you live alone?",
                    "lives_alone",
                    parse_yes_no,
                    3,
                    ("yes", "no"),
                ),
                entry("language", "Which language do you prefer?", "language", parse_language, 4),
                entry(
                    "hearing", "Do you hear me well?", "hearing", parse_hearing, 4, ("yes", "no")
                ),
                entry(
                    "favorite_room",
                    "Which room of the house do you like best?",
                    "favorite_room",
                    parse_room,
                    5,
                ),
            ]
        )

    def get(self, question_id: str) -> Question | None:
        """The question with this id, None if the bank has none."""
        entry = self._entries.get(question_id)
        return entry.question if entry else None

    @property
    def questions(self) -> tuple[Question, ...]:
        """Every question, in the bank's order."""
        return tuple(entry.question for entry in self._entries.values())

    def next_question(
        self, profile: Profile, rng: random.Random, asked: Collection[str]
    ) -> Question | None:
        """A question whose field the profile lacks and that was not ``asked`` yet;
        the most useful priority first, chosen at random within it. None when full."""
        open_entries = [
            entry
            for entry in self._entries.values()
            if entry.question.id not in asked and profile.missing(entry.question.field)
        ]
        if not open_entries:
            return None
        best = min(entry.priority for entry in open_entries)
        return rng.choice([entry.question for entry in open_entries if entry.priority == best])

    def parse(self, question: Question, answer_text: str) -> dict[str, Any] | None:
        """The fields to store from ``answer_text``; None when it was not understood."""
        entry = self._entries.get(question.id)
        if entry is None or not isinstance(answer_text, str):
            return None
        value = entry.parse(answer_text)
        return None if value is None else {question.field: value}
