"""``dms users list|show|export|erase`` on a real database, also while a daemon holds it."""

from __future__ import annotations

import json
from datetime import timedelta
from pathlib import Path

from sqlalchemy import text
from typer.testing import CliRunner

from memory import ProfileNotFound, ProfileStore
from memory.cli import app
from tests.memory.conftest import NOW


def _run(*args: str) -> tuple[int, str, BaseException | None]:
    result = CliRunner().invoke(app, list(args))
    error = result.exception if not isinstance(result.exception, SystemExit) else None
    return result.exit_code, result.output, error


def _fill(store: ProfileStore) -> None:
    for user in ("bob", "ann"):
        store.get_or_create(user, NOW)
        store.update(user, NOW, name=user.title(), age=80)
        session = store.start_session(user, NOW)
        store.record_activity(
            user, "quiz", NOW, NOW + timedelta(minutes=3), "completed", "robot", False, session
        )
        store.record_feedback(user, "quiz", 1.0, NOW)


def test_list_show_export(store: ProfileStore, db_url: str) -> None:
    _fill(store)
    code, out, _ = _run("list", "--json", "--db", db_url)
    assert (code, json.loads(out)) == (0, {"users": ["ann", "bob"]})
    code, out, _ = _run("show", "ann", "--db", db_url)
    shown = json.loads(out)
    assert code == 0 and shown["name"] == "Ann" and shown["age"] == 80
    assert "sessions" not in shown
    code, out, _ = _run("export", "ann", "--db", db_url)
    exported = json.loads(out)
    assert code == 0
    assert exported["profile"]["name"] == "Ann"
    assert [run["activity"] for run in exported["activities"]] == ["quiz"]
    assert exported["feedback"][0]["score"] == 1.0


def test_erase_while_the_daemon_holds_the_database(store: ProfileStore, db_url: str) -> None:
    _fill(store)
    # The daemon is in the middle of a read when the erase comes.
    with store.engine.connect() as daemon_connection:
        daemon_connection.execute(text("SELECT COUNT(*) FROM users")).scalar_one()
        code, out, error = _run("erase", "ann", "--yes", "--db", db_url)
        assert (code, error) == (0, None)
        assert "erased ann" in out
    assert store.list_ids() == ["bob"]
    # The daemon keeps writing after the erase.
    store.record_feedback("bob", "dance", 0.5, NOW)
    code, out, _ = _run("list", "--json", "--db", db_url)
    assert json.loads(out) == {"users": ["bob"]}


def test_unknown_user_is_a_one_line_error(store: ProfileStore, db_url: str) -> None:
    for command in ("show", "export", "erase"):
        code, _, error = _run(command, "nobody", "--db", db_url)
        assert code != 0
        assert isinstance(error, ProfileNotFound)
        assert str(error) == "no profile for user 'nobody'"


def test_users_add_registers_a_user_the_agenda_then_accepts(tmp_path: Path) -> None:
    url = f"sqlite:///{tmp_path / 'dms.db'}"
    ProfileStore(url).close()  # the daemon's database (the CLI never creates one)
    runner = CliRunner()
    bad = runner.invoke(app, ["add", "ann", "--set", "age=300", "--db", url])
    assert bad.exit_code != 0 and "age" in str(bad.exception)
    listed = runner.invoke(app, ["list", "--json", "--db", url]).output
    assert json.loads(listed) == {"users": []}  # nothing stored
    added = runner.invoke(app, ["add", "ann", "--set", "name=Ann", "--set", "age=81", "--db", url])
    assert added.exit_code == 0, added.output
    profile = json.loads(added.output)
    assert (profile["name"], profile["age"]) == ("Ann", 81)
    from agenda.cli import app as agenda_app

    reminder = runner.invoke(
        agenda_app,
        [
            "add",
            "--user",
            "ann",
            "--reminder",
            "The doctor",
            "--at",
            "2030-01-01T17:00",
            "--db",
            url,
        ],
    )
    assert reminder.exit_code == 0, reminder.output
