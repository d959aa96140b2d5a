"""``dms users export|erase`` cover the agenda too: its items and log are the user's data.

On a real SQLite file shared by the profile store and the agenda, as in the daemon.
"""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Iterator
from datetime import timedelta
from pathlib import Path

import pytest
from sqlalchemy import text
from typer.testing import CliRunner

from agenda import Agenda, ItemSpec, Outcome
from memory import ProfileStore
from memory.cli import app
from tests.memory.conftest import NOW

HOUR = timedelta(hours=1)
GRACE = timedelta(seconds=600)


@pytest.fixture
def db_path(tmp_path: Path) -> Path:
    return tmp_path / "dms.db"


@pytest.fixture
def daemon(db_path: Path) -> Iterator[tuple[ProfileStore, Agenda]]:
    """The daemon's store and agenda on one database file."""
    url = f"sqlite:///{db_path}"
    store = ProfileStore(url)
    agenda = Agenda.open(url, user_exists=lambda user: user in store.list_ids())
    yield store, agenda
    agenda.close()
    store.close()


def _cli(*args: str) -> tuple[int, str]:
    result = CliRunner().invoke(app, list(args))
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        raise result.exception
    return result.exit_code, result.output


def _fill(store: ProfileStore, agenda: Agenda) -> None:
    """Two users, each with history, a reminder, an event, one delivery and one miss."""
    for user in ("ann", "bob"):
        store.get_or_create(user, NOW)
        store.update(user, NOW, name=user.title(), age=80)
        session = store.start_session(user, NOW)
        store.record_activity(user, "quiz", NOW, NOW + HOUR, "completed", "robot", False, session)
        store.record_feedback(user, "quiz", 1.0, NOW, write_id=f"{user}-feedback")  # as daemons do
        store.record_feedback(user, "dance", 0.2, NOW)
        store.record_answer(user, "favorite_music", "boleros", NOW)
        store.record_interactions(
            user, session, [{"seq": 0, "at": NOW, "event": "arrived"}], write_id=f"{user}-arrived"
        )
        store.end_session(session, NOW + HOUR)
        agenda.add(ItemSpec(user_id=user, kind="reminder", text="Pills", every=3600), NOW)
        agenda.add(ItemSpec(user_id=user, kind="event", activity="quiz", at=NOW + 5 * HOUR), NOW)
    for user in ("ann", "bob"):
        (due,) = agenda.due(NOW + HOUR, user)
        agenda.delivered(due, NOW + HOUR)
    agenda.due(NOW + 2 * HOUR + GRACE + timedelta(seconds=1), None)  # both miss the second
    outcomes = sorted((o.user_id, o.outcome) for o in agenda.history(None))
    assert outcomes == [
        ("ann", Outcome.DELIVERED),
        ("ann", Outcome.MISSED),
        ("bob", Outcome.DELIVERED),
        ("bob", Outcome.MISSED),
    ]


def _rows_of(db_path: Path, user_id: str) -> dict[str, int]:
    """Rows per table whose ``user_id`` is ``user_id``, over every table that has one."""
    with sqlite3.connect(db_path) as connection:
        tables = [
            name
            for (name,) in connection.execute("SELECT name FROM sqlite_master WHERE type='table'")
            if any(
                column[1] == "user_id"
                for column in connection.execute(f'PRAGMA table_info("{name}")')
            )
        ]
        return {
            table: int(
                connection.execute(
                    f'SELECT count(*) FROM "{table}" WHERE user_id = ?', (user_id,)
                ).fetchone()[0]
            )
            for table in tables
        }


def test_export_holds_the_users_agenda_items_and_log(
    daemon: tuple[ProfileStore, Agenda], db_path: Path
) -> None:
    _fill(*daemon)
    code, out = _cli("export", "ann", "--db", str(db_path))
    exported = json.loads(out)
    assert code == 0
    items, log = exported["agenda"]["items"], exported["agenda"]["log"]
    assert [(i["user_id"], i["kind"], i["text"], i["activity"]) for i in items] == [
        ("ann", "reminder", "Pills", None),
        ("ann", "event", None, "quiz"),
    ]
    assert [(o["user_id"], o["outcome"], o["what"]) for o in log] == [
        ("ann", "delivered", "Pills"),
        ("ann", "missed", "Pills"),
    ]
    assert log[0]["fire_time"] == (NOW + HOUR).isoformat()
    assert [s["ended"] for s in exported["sessions"]] == [(NOW + HOUR).isoformat()]


def test_erase_removes_every_row_of_the_user_in_every_table_and_no_other(
    daemon: tuple[ProfileStore, Agenda], db_path: Path
) -> None:
    _fill(*daemon)
    bob_before = _rows_of(db_path, "bob")
    ann_before = _rows_of(db_path, "ann")
    # Every table that names a user holds some of ann's rows, agenda included.
    assert {"agenda_items", "agenda_occurrences", "users", "sessions"} <= set(ann_before)
    assert all(count > 0 for count in ann_before.values()), ann_before
    code, out = _cli("erase", "ann", "--yes", "--db", str(db_path))
    assert code == 0 and "erased ann" in out
    assert set(_rows_of(db_path, "ann").values()) == {0}
    assert _rows_of(db_path, "bob") == bob_before


def test_erase_while_the_daemon_holds_the_database_does_not_bring_the_user_back(
    daemon: tuple[ProfileStore, Agenda], db_path: Path
) -> None:
    store, agenda = daemon
    _fill(store, agenda)
    with store.engine.connect() as reading:
        reading.execute(text("SELECT count(*) FROM agenda_items")).scalar_one()
        code, _ = _cli("erase", "ann", "--yes", "--db", str(db_path))
        assert code == 0
    # The daemon's agenda still holds ann's items in memory; its next misses and
    # deliveries must not write her log again.
    later = NOW + 6 * HOUR + GRACE + timedelta(seconds=1)
    assert agenda.due(later, "ann") == []
    assert {o.user_id for o in agenda.history(None)} == {"bob"}
    assert set(_rows_of(db_path, "ann").values()) == {0}
    assert [u.user_id for u in agenda.upcoming(None, later)] == ["bob"]
    # bob's agenda goes on: his reminder and his event were missed since.
    assert {o.what for o in agenda.history("bob", Outcome.MISSED)} == {"Pills", "quiz"}


def test_the_agenda_exports_and_erases_one_user_itself(
    daemon: tuple[ProfileStore, Agenda], db_path: Path
) -> None:
    store, agenda = daemon
    _fill(store, agenda)
    exported = agenda.export_user("ann")
    assert [i["kind"] for i in exported["items"]] == ["reminder", "event"]
    assert [o["outcome"] for o in exported["log"]] == ["delivered", "missed"]
    assert [c["claimed_by"] for c in exported["claims"]] == [agenda.claimer]  # the delivery's
    agenda.erase_user("ann")
    assert agenda.export_user("ann") == {"items": [], "log": [], "claims": []}
    assert agenda.due(NOW + 3 * HOUR, "ann") == []
    rows = _rows_of(db_path, "ann")
    assert rows["agenda_items"] == rows["agenda_occurrences"] == rows["agenda_claims"] == 0
    assert rows["users"] == 1  # the profile is the store's to erase
    assert len(agenda.export_user("bob")["items"]) == 2


def test_a_database_without_the_agenda_exports_no_agenda(db_path: Path) -> None:
    store = ProfileStore(f"sqlite:///{db_path}")
    try:
        store.get_or_create("ann", NOW)
        assert "agenda" not in store.export("ann")
        store.erase("ann")
        assert store.list_ids() == []
    finally:
        store.close()
