"""Schema migrations: a database made by the previous schema upgrades without loss."""

from __future__ import annotations

from datetime import timedelta

import pytest
from sqlalchemy import text
from typer.testing import CliRunner

from dms.cli import db_app
from memory import ProfileStore, SchemaOutOfDate, migrations
from memory.db import make_engine
from tests.memory.conftest import NOW

PREVIOUS = "memory_0001"


def _fill_previous_schema(url: str) -> None:
    """A database at memory_0001 with two users and their history, written as that
    schema's code would have (no favorite_room, no parsed answers)."""
    engine = make_engine(url)
    migrations.upgrade_engine(engine, PREVIOUS)
    later = NOW + timedelta(minutes=5)
    with engine.begin() as connection:
        for user, age in (("ann", 74), ("bob", 81)):
            connection.execute(
                text(
                    "INSERT INTO users (user_id, created_at, updated_at, name, age, sex,"
                    " interaction_style, proactivity, proactivity_confidence, attributes,"
                    " voice_failures, screen_failures, initiative_taken, initiative_offered)"
                    " VALUES (:u, :t, :t, :n, :a, 'female', 'screen', 'low', 0.5,"
                    " :attrs, 1, 0, 2, 9)"
                ),
                {"u": user, "t": NOW, "n": user.title(), "a": age, "attrs": '{"hobbies": "music"}'},
            )
            connection.execute(
                text("INSERT INTO activity_scores VALUES (:u, 'quiz', 1.5, 2, 1, 0)"),
                {"u": user},
            )
            session_id = connection.execute(
                text(
                    "INSERT INTO sessions (user_id, started_at, ended_at)"
                    " VALUES (:u, :t, :l) RETURNING id"
                ),
                {"u": user, "t": NOW, "l": later},
            ).scalar_one()
            connection.execute(
                text(
                    "INSERT INTO activity_runs (user_id, session_id, activity, started_at,"
                    " ended_at, outcome, chosen_by, cancelled)"
                    " VALUES (:u, :s, 'quiz', :t, :l, 'completed', 'robot', false)"
                ),
                {"u": user, "s": session_id, "t": NOW, "l": later},
            )
            connection.execute(
                text(
                    "INSERT INTO feedback (user_id, activity, score, at)"
                    " VALUES (:u, 'quiz', 0.75, :l)"
                ),
                {"u": user, "l": later},
            )
            connection.execute(
                text(
                    "INSERT INTO answers (user_id, question_id, answer, at)"
                    " VALUES (:u, 'age', :a, :l)"
                ),
                {"u": user, "a": str(age), "l": later},
            )
    engine.dispose()


def test_the_store_refuses_an_out_of_date_schema_and_says_what_to_run(db_url: str) -> None:
    _fill_previous_schema(db_url)
    with pytest.raises(SchemaOutOfDate) as caught:
        ProfileStore(db_url)
    message = str(caught.value)
    assert "dms db upgrade --db" in message
    assert PREVIOUS in message and migrations.head() in message
    assert "\n" not in message


def test_upgrade_keeps_every_row_of_the_previous_schema(db_url: str) -> None:
    _fill_previous_schema(db_url)
    result = CliRunner().invoke(db_app, ["upgrade", "--db", db_url])
    assert result.exit_code == 0, result.output
    assert f"profiles: {PREVIOUS} -> {migrations.head()}" in result.output
    store = ProfileStore(db_url)
    try:
        assert store.list_ids() == ["ann", "bob"]
        for user, age in (("ann", 74), ("bob", 81)):
            data = store.export(user)
            profile = data["profile"]
            assert (profile["name"], profile["age"], profile["sex"]) == (
                user.title(),
                age,
                "female",
            )
            assert profile["interaction_style"] == "screen"
            assert (profile["proactivity"], profile["proactivity_confidence"]) == ("low", 0.5)
            assert profile["attributes"] == {"hobbies": "music"}
            assert (profile["initiative_taken"], profile["initiative_offered"]) == (2, 9)
            assert profile["voice_failures"] == 1
            assert profile["scores"]["quiz"] == {
                "feedback_sum": 1.5,
                "feedback_count": 2,
                "completions": 1,
                "cancellations": 0,
            }
            assert profile["favorite_room"] is None
            assert len(data["sessions"]) == 1 and data["sessions"][0]["ended"] is not None
            assert data["activities"][0]["outcome"] == "completed"
            assert data["feedback"] == [
                {
                    "activity": "quiz",
                    "score": 0.75,
                    "time": (NOW + timedelta(minutes=5)).isoformat(),
                }
            ]
            assert data["answers"][0]["answer"] == str(age)
            assert data["answers"][0]["applied"] is None
        # The new column works.
        assert store.update("ann", NOW, favorite_room="garden").favorite_room == "garden"
    finally:
        store.close()
    # Upgrading again is a no-op.
    again = CliRunner().invoke(db_app, ["upgrade", "--db", db_url])
    assert again.exit_code == 0
    assert f"profiles: {migrations.head()} -> {migrations.head()}" in again.output


def test_a_new_database_is_created_at_head_beside_the_agenda(db_url: str) -> None:
    from agenda import Agenda

    Agenda.open(db_url).close()
    store = ProfileStore(db_url)
    try:
        with store.engine.connect() as connection:
            assert migrations.current(connection) == migrations.head()
        store.get_or_create("ann", NOW)
    finally:
        store.close()


def test_upgrade_of_an_unreadable_database_is_one_line(tmp_path: object) -> None:
    from pathlib import Path

    assert isinstance(tmp_path, Path)
    bad = tmp_path / "bad.db"
    bad.write_bytes(b"garbage" * 200)
    result = CliRunner().invoke(db_app, ["upgrade", "--db", f"sqlite:///{bad}"])
    assert result.exit_code != 0
    assert result.exception is not None
    assert "cannot upgrade" in str(result.exception)
    assert "\n" not in str(result.exception)
