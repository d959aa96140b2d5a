"""General questions: the bank fills missing fields and understands plain answers."""

from __future__ import annotations

import random

import pytest

from memory import ProfileStore, QuestionBank
from tests.memory.conftest import NOW

BANK = QuestionBank.default()


@pytest.mark.parametrize(
    ("question_id", "answer", "expected"),
    [
        ("age", "74", {"age": 74}),
        ("age", "I am 81 years old", {"age": 81}),
        ("age", "seventy four", {"age": 74}),
        ("age", "I don't know", None),
        ("age", "250", None),
        ("name", "my name is Alice", {"name": "Alice"}),
        ("name", "bernard", {"name": "Bernard"}),
        ("name", "12345", None),
        ("sex", "female", {"sex": "female"}),
        ("sex", "I'm a man", {"sex": "male"}),
        ("sex", "pass", None),
        ("lives_alone", "yes", {"lives_alone": True}),
        ("lives_alone", "No, with my daughter", {"lives_alone": False}),
        ("lives_alone", "maybe", None),
        ("hobbies", "Gardening", {"hobbies": "gardening"}),
        ("hobbies", "maybe", None),
        ("language", "I speak Spanish", {"language": "spanish"}),
        ("language", "Klingon", None),
        ("hearing", "not well", {"hearing": False}),
        ("hearing", "yes", {"hearing": True}),
        ("favorite_room", "the living room", {"favorite_room": "living room"}),
        ("robot_initiative_frequency", "high please", {"robot_initiative_frequency": "high"}),
    ],
)
def test_answers_are_parsed_into_fields(
    question_id: str, answer: str, expected: dict[str, object] | None
) -> None:
    question = BANK.get(question_id)
    assert question is not None
    assert BANK.parse(question, answer) == expected


def test_next_question_fills_missing_fields_until_none_is_left(store: ProfileStore) -> None:
    profile = store.get_or_create("ann", NOW)
    rng = random.Random(3)
    first = BANK.next_question(profile, rng, set())
    assert first is not None and first.field == "name"  # the most useful first
    answers = {
        "name": "Ann",
        "age": "70",
        "sex": "female",
        "occupation": "teacher",
        "education": "university",
        "hobbies": "music",
        "lives_alone": "no",
        "language": "english",
        "hearing": "yes",
        "favorite_room": "kitchen",
        "robot_initiative_frequency": "low",
    }
    asked: set[str] = set()
    while (question := BANK.next_question(profile, rng, asked)) is not None:
        assert profile.missing(question.field)
        asked.add(question.id)
        profile = store.record_answer("ann", question.id, answers[question.id], NOW)
        assert not profile.missing(question.field)
    assert asked == set(answers)
    assert profile.attributes["occupation"] == "teacher"
    assert profile.language == "english" and profile.hearing is True
    assert len(store.export("ann")["answers"]) == len(answers)


def test_asked_questions_are_not_repeated(store: ProfileStore) -> None:
    profile = store.get_or_create("ann", NOW)
    every = {question.id for question in BANK.questions}
    assert BANK.next_question(profile, random.Random(1), every) is None
    question = BANK.next_question(profile, random.Random(1), every - {"hobbies"})
    assert question is not None and question.id == "hobbies"


def test_an_answer_not_understood_is_kept_but_fills_nothing(store: ProfileStore) -> None:
    store.get_or_create("ann", NOW)
    profile = store.record_answer("ann", "age", "I'd rather not say", NOW)
    assert profile.age is None
    profile = store.record_answer("ann", "unknown_question", "whatever", NOW)
    answers = store.export("ann")["answers"]
    assert [(a["question"], a["applied"]) for a in answers] == [
        ("age", None),
        ("unknown_question", None),
    ]
    assert profile.age is None
