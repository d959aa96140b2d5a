"""The profile store on a real database: profiles, history, privacy, Table 2, errors."""

from __future__ import annotations

import json
import sqlite3
import threading
from datetime import timedelta
from pathlib import Path

import pytest

from memory import (
    ProfileError,
    ProfileNotFound,
    ProfileStore,
    StoreUnavailable,
)
from memory.errors import StoreDamaged, StoreRefused
from memory.parameters import user_parameter_types
from memory.proactivity import MIN_CHANCES
from memory.store import FAILURES_TO_SWITCH
from tests.memory.conftest import NOW

LATER = NOW + timedelta(minutes=10)


def test_new_user_gets_an_empty_profile_that_persists(store: ProfileStore, db_url: str) -> None:
    profile = store.get_or_create("ann", NOW)
    assert profile.user_id == "ann"
    assert profile.name is None and profile.age is None
    assert profile.interaction_style == "voice"
    assert profile.proactivity == "unknown"
    assert profile.created_at == NOW
    store.update("ann", LATER, name="Ann", age=74)
    store.close()
    reopened = ProfileStore(db_url)
    try:
        again = reopened.get_or_create("ann", LATER)
        assert (again.name, again.age, again.created_at) == ("Ann", 74, NOW)
        assert reopened.list_ids() == ["ann"]
    finally:
        reopened.close()


def test_profile_is_a_frozen_snapshot(store: ProfileStore) -> None:
    profile = store.get_or_create("ann", NOW)
    with pytest.raises(ValueError):
        setattr(profile, "age", 3)  # noqa: B010 (a frozen model refuses it at run time)
    store.update("ann", NOW, age=80)
    assert profile.age is None
    assert store.get("ann").age == 80


def test_params_are_flat_and_leave_unset_fields_out(store: ProfileStore) -> None:
    store.get_or_create("ann", NOW)
    profile = store.update(
        "ann",
        NOW,
        name="Ann",
        age=74,
        gender="female",
        hearing=False,
        bondlevel=4,
        favoriteroom="kitchen",
        hobbies="music",
        lives_alone=True,
    )
    params = profile.params()
    assert params["name"] == "Ann"
    assert params["age"] == 74
    assert params["sex"] == "female"
    assert params["hearing"] is False
    assert params["bondlevel"] == 4
    assert params["favorite_room"] == "kitchen"
    assert params["hobbies"] == "music"
    assert params["lives_alone"] is True
    assert params["interaction_style"] == "voice"
    assert params["proactivity"] == "unknown"
    assert params["likes"] == frozenset()
    assert "language" not in params and "volume" not in params
    types = user_parameter_types()
    for name in ("name", "age", "sex", "hearing", "bondlevel", "favorite_room", "proactivity"):
        assert name in types
    assert types["age"] == "number" and types["hearing"] == "boolean" and types["likes"] == "set"


@pytest.mark.parametrize(
    ("fields", "named"),
    [
        ({"age": -1}, "age"),
        ({"age": 200}, "age"),
        ({"age": "seventy"}, "age"),
        ({"age": True}, "age"),
        ({"age": 70.5}, "age"),
        ({"sex": "robot"}, "sex"),
        ({"hearing": "yes"}, "hearing"),
        ({"interaction_style": "telepathy"}, "interaction_style"),
        ({"interaction_style": None}, "interaction_style"),
        ({"proactivity": "extreme"}, "proactivity"),
        ({"proactivity_confidence": 1.5}, "proactivity_confidence"),
        ({"volume": float("nan")}, "volume"),
        ({"volume": 101}, "volume"),
        ({"bondlevel": 9}, "bondlevel"),
        ({"name": ""}, "name"),
        ({"name": "x" * 201}, "name"),
        ({"Bad Name": 1}, "Bad Name"),
        ({"pets\n": 1}, "pets"),  # a name ending in a line break is not a name
        ({"likes": "dance"}, "likes"),
        ({"pets": ["cat"]}, "pets"),
    ],
)
def test_invalid_values_are_refused_naming_the_field(
    store: ProfileStore, fields: dict[str, object], named: str
) -> None:
    store.get_or_create("ann", NOW)
    store.update("ann", NOW, age=70, name="Ann")
    with pytest.raises(ProfileError) as caught:
        store.update("ann", LATER, **fields)
    message = str(caught.value)
    assert named in message
    assert "\n" not in message
    kept = store.get("ann")
    assert (kept.age, kept.name, kept.updated_at) == (70, "Ann", NOW)


def test_none_clears_a_field_and_removes_an_attribute(store: ProfileStore) -> None:
    store.get_or_create("ann", NOW)
    store.update("ann", NOW, age=70, pets="cat")
    profile = store.update("ann", NOW, age=None, pets=None)
    assert profile.age is None
    assert "pets" not in profile.attributes


def test_unknown_user(store: ProfileStore) -> None:
    with pytest.raises(ProfileNotFound) as caught:
        store.get("nobody")
    assert isinstance(caught.value, KeyError)
    assert str(caught.value) == "no profile for user 'nobody'"
    for call in (
        lambda: store.update("nobody", NOW, age=3),
        lambda: store.erase("nobody"),
        lambda: store.export("nobody"),
        lambda: store.start_session("nobody", NOW),
        lambda: store.record_feedback("nobody", "quiz", 0.5, NOW),
    ):
        with pytest.raises(ProfileNotFound):
            call()


def _history(store: ProfileStore, user: str) -> int:
    store.get_or_create(user, NOW)
    session = store.start_session(user, NOW)
    store.record_activity(user, "quiz", NOW, LATER, "completed", "robot", False, session)
    store.record_activity(user, "dance", LATER, LATER, "cancelled", "user", True, session)
    store.record_feedback(user, "quiz", 0.75, LATER)
    store.record_answer(user, "age", "I am 81 years old", LATER)
    store.end_session(session, LATER)
    return session


def test_export_holds_everything_and_is_json(store: ProfileStore) -> None:
    session = _history(store, "ann")
    data = store.export("ann")
    json.dumps(data)
    assert data["profile"]["age"] == 81
    assert data["sessions"] == [
        {"id": session, "started": NOW.isoformat(), "ended": LATER.isoformat(), "metrics": None}
    ]
    assert [(a["activity"], a["cancelled"], a["chosen_by"]) for a in data["activities"]] == [
        ("quiz", False, "robot"),
        ("dance", True, "user"),
    ]
    assert data["feedback"] == [{"activity": "quiz", "score": 0.75, "time": LATER.isoformat()}]
    assert data["answers"][0]["applied"] == {"age": 81}
    scores = data["profile"]["scores"]
    assert scores["quiz"]["completions"] == 1 and scores["quiz"]["feedback_count"] == 1
    assert scores["dance"]["cancellations"] == 1


def test_erase_removes_everything_and_only_that_user(store: ProfileStore) -> None:
    _history(store, "ann")
    _history(store, "bob")
    store.erase("ann")
    assert store.list_ids() == ["bob"]
    with pytest.raises(ProfileNotFound):
        store.export("ann")
    bob = store.export("bob")
    assert len(bob["activities"]) == 2 and len(bob["feedback"]) == 1
    # Nothing of ann's is left in any table.
    from sqlalchemy import text

    with store.engine.connect() as connection:
        for table in (
            "users",
            "activity_scores",
            "sessions",
            "activity_runs",
            "feedback",
            "answers",
        ):
            count = connection.execute(
                text(f"SELECT COUNT(*) FROM {table} WHERE user_id = 'ann'")
            ).scalar_one()
            assert count == 0, table
    # A new ann starts from nothing.
    assert store.get_or_create("ann", LATER).scores == {}


def test_feedback_and_runs_update_the_users_scores(store: ProfileStore) -> None:
    store.get_or_create("ann", NOW)
    store.record_feedback("ann", "quiz", 1.0, NOW)
    store.record_feedback("ann", "quiz", 0.8, NOW)
    store.record_activity("ann", "bingo", NOW, LATER, "cancelled", "robot", True)
    profile = store.record_activity("ann", "bingo", NOW, LATER, "failed", "robot", False)
    quiz, bingo = profile.scores["quiz"], profile.scores["bingo"]
    assert quiz.mean() == pytest.approx(0.9)
    assert bingo.cancellations == 1 and bingo.completions == 0
    bingo_mean = bingo.mean()
    assert bingo_mean is not None and bingo_mean < 0.5
    assert profile.likes() == frozenset({"quiz"})
    assert profile.params()["likes"] == frozenset({"quiz"})


@pytest.mark.parametrize("score", [-0.1, 1.1, float("nan"), "high", True])
def test_bad_feedback_is_refused(store: ProfileStore, score: object) -> None:
    store.get_or_create("ann", NOW)
    with pytest.raises(ProfileError, match="score"):
        store.record_feedback("ann", "quiz", score, NOW)  # type: ignore[arg-type]
    assert store.export("ann")["feedback"] == []


def test_bad_activity_records_are_refused(store: ProfileStore) -> None:
    store.get_or_create("ann", NOW)
    with pytest.raises(ProfileError, match="ended"):
        store.record_activity("ann", "quiz", LATER, NOW, "completed", "robot", False)
    with pytest.raises(ProfileError, match="session_id"):
        store.record_activity("ann", "quiz", NOW, LATER, "completed", "robot", False, 999)
    with pytest.raises(ProfileError, match="now"):
        store.get_or_create("bob", NOW.replace(tzinfo=None))
    assert store.export("ann")["activities"] == []


def test_repeated_unanswered_prompts_switch_the_interaction_style(store: ProfileStore) -> None:
    store.get_or_create("ann", NOW)
    for _ in range(FAILURES_TO_SWITCH - 1):
        profile = store.record_interaction("ann", "voice", False, NOW)
    assert profile.interaction_style == "voice"
    # An answer in between resets the count.
    store.record_interaction("ann", "voice", True, NOW)
    for _ in range(FAILURES_TO_SWITCH - 1):
        profile = store.record_interaction("ann", "voice", False, NOW)
    assert profile.interaction_style == "voice"
    profile = store.record_interaction("ann", "voice", False, NOW)
    assert profile.interaction_style == "screen"
    assert store.get("ann").interaction_style == "screen"
    # Failing on the screen too goes back to voice.
    for _ in range(FAILURES_TO_SWITCH):
        profile = store.record_interaction("ann", "screen", False, NOW)
    assert profile.interaction_style == "voice"
    with pytest.raises(ProfileError, match="channel"):
        store.record_interaction("ann", "smoke", False, NOW)


@pytest.mark.parametrize(
    ("pattern", "level"),
    [([True] * 12, "high"), ([False] * 12, "low"), ([True, False] * 6, "moderate")],
)
def test_proactivity_is_estimated_with_growing_confidence(
    store: ProfileStore, pattern: list[bool], level: str
) -> None:
    store.get_or_create("ann", NOW)
    confidences = []
    for index, took in enumerate(pattern):
        profile = store.record_initiative("ann", took, NOW)
        confidences.append(profile.proactivity_confidence)
        if index + 1 < MIN_CHANCES:
            assert profile.proactivity == "unknown"
    assert profile.proactivity == level
    assert store.get("ann").proactivity == level
    assert confidences == sorted(confidences)
    assert 0 < confidences[0] < confidences[-1] < 1


def test_concurrent_writers_lose_nothing(store: ProfileStore) -> None:
    store.get_or_create("ann", NOW)
    errors: list[BaseException] = []

    def write(worker: int) -> None:
        try:
            for index in range(10):
                store.record_feedback("ann", f"act{worker}", index / 10, NOW)
        except BaseException as error:  # collected and asserted below
            errors.append(error)

    threads = [threading.Thread(target=write, args=(n,)) for n in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert errors == []
    assert len(store.export("ann")["feedback"]) == 40
    assert all(score.feedback_count == 10 for score in store.get("ann").scores.values())


def test_get_or_create_from_many_threads_makes_one_profile(store: ProfileStore) -> None:
    results: list[str] = []
    barrier = threading.Barrier(4)

    def create() -> None:
        barrier.wait()
        results.append(store.get_or_create("zoe", NOW).user_id)

    threads = [threading.Thread(target=create) for _ in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert results == ["zoe"] * 4
    assert store.list_ids() == ["zoe"]


def test_a_database_that_cannot_be_opened_is_one_line(tmp_path: Path) -> None:
    not_a_db = tmp_path / "garbage.db"
    not_a_db.write_bytes(b"this is not sqlite" * 100)
    for url in (f"sqlite:///{not_a_db}", "nosuchdriver://x/y", "not a url at all"):
        with pytest.raises(ProfileError) as caught:
            ProfileStore(url)
        assert "\n" not in str(caught.value)
        assert not isinstance(caught.value, StoreUnavailable)


def test_a_missing_table_refuses_the_write_for_good(tmp_path: Path) -> None:
    path = tmp_path / "dms.db"
    store = ProfileStore(f"sqlite:///{path}")
    store.get_or_create("ann", NOW)
    from sqlalchemy import text

    with store.engine.begin() as connection:
        connection.execute(text("DROP TABLE feedback"))
    with pytest.raises(StoreRefused) as caught:
        store.record_feedback("ann", "quiz", 0.5, NOW)
    assert "\n" not in str(caught.value) and "no such table: feedback" in str(caught.value)
    assert store.get("ann").scores == {}
    store.close()


def test_a_lock_held_by_another_process_is_store_unavailable(tmp_path: Path) -> None:
    path = tmp_path / "dms.db"
    store = ProfileStore(f"sqlite:///{path}", busy_timeout_s=0.05)
    store.get_or_create("ann", NOW)
    holder = sqlite3.connect(path, isolation_level=None)
    holder.execute("BEGIN EXCLUSIVE")
    try:
        with pytest.raises(StoreUnavailable) as caught:
            store.record_feedback("ann", "quiz", 0.5, NOW)
        assert "database is locked" in str(caught.value)
    finally:
        holder.execute("ROLLBACK")
        holder.close()
    assert store.record_feedback("ann", "quiz", 0.5, NOW).scores["quiz"].feedback_count == 1
    store.close()


def test_a_dropped_table_is_refused_at_open_with_the_repair(tmp_path: Path) -> None:
    url = f"sqlite:///{tmp_path / 'dms.db'}"
    ProfileStore(url).close()
    with sqlite3.connect(tmp_path / "dms.db") as connection:
        connection.execute("DROP TABLE activity_runs")
    with pytest.raises(StoreDamaged) as caught:
        ProfileStore(url)
    line = str(caught.value)
    assert "\n" not in line and "activity_runs" in line
    assert "restore a backup" in line and f"dms db upgrade --db {url}" in line
