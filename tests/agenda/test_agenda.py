"""The agenda on virtual time: due, delivered, missed, restarts, priorities, bad input."""

from __future__ import annotations

import sqlite3
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

import pytest

from agenda import Agenda, AgendaError, AgendaNotFound, ItemSpec, Outcome, migrations
from tests.agenda.conftest import START

S = timedelta(seconds=1)
MIN = timedelta(minutes=1)


def reminder(**extra: Any) -> ItemSpec:
    fields: dict[str, Any] = {"user_id": "ann", "kind": "reminder", "text": "The doctor at five"}
    fields.update(extra)
    return ItemSpec(**fields)


def event(**extra: Any) -> ItemSpec:
    fields: dict[str, Any] = {"user_id": "ann", "kind": "event", "activity": "quiz"}
    fields.update(extra)
    return ItemSpec(**fields)


def _rows(db_url: str, table: str) -> int:
    path = db_url.removeprefix("sqlite:///")
    with sqlite3.connect(path) as connection:
        return int(connection.execute(f"SELECT count(*) FROM {table}").fetchone()[0])


def test_a_reminder_is_due_at_its_lead_time_for_its_user_only(agenda: Agenda) -> None:
    at = START + timedelta(hours=2)
    item = agenda.add(reminder(at=at, lead_s=600), START)
    assert item.next_fire == at
    assert agenda.due(at - 11 * MIN, "ann") == []
    assert agenda.due(at - 10 * MIN, "bob") == []
    (due,) = agenda.due(at - 10 * MIN, "ann")
    assert (due.item_id, due.kind, due.text) == (item.item_id, "reminder", "The doctor at five")
    assert due.fire_time == at and due.due_at == at - 10 * MIN
    assert agenda.due(at - 10 * MIN, None) == []


def test_a_delivered_occurrence_never_comes_back_and_the_next_one_is_scheduled(
    agenda: Agenda,
) -> None:
    item = agenda.add(event(every=3600), START)
    first = START + timedelta(hours=1)
    (due,) = agenda.due(first, "ann")
    agenda.delivered(due, first)
    assert agenda.due(first, "ann") == []
    assert agenda.due(first + 30 * MIN, "ann") == []
    with pytest.raises(AgendaError, match="already delivered or missed"):
        agenda.delivered(due, first)
    (following,) = agenda.due(first + timedelta(hours=1), "ann")
    assert following.item_id == item.item_id
    assert following.fire_time == first + timedelta(hours=1)
    history = agenda.history("ann")
    assert [(h.outcome, h.fire_time) for h in history] == [(Outcome.DELIVERED, first)]


def test_high_priority_comes_first_then_the_earlier_fire_time(agenda: Agenda) -> None:
    at = START + timedelta(hours=1)
    normal_early = agenda.add(reminder(at=at - MIN), START)
    high_late = agenda.add(event(at=at, priority="high"), START)
    normal_late = agenda.add(reminder(at=at, text="Water the plants"), START)
    due = agenda.due(at, "ann")
    assert [d.item_id for d in due] == [
        high_late.item_id,
        normal_early.item_id,
        normal_late.item_id,
    ]
    assert due[0].priority == "high"


def test_a_user_who_comes_back_within_grace_still_gets_the_item(agenda: Agenda) -> None:
    at = START + timedelta(hours=1)
    agenda.add(reminder(at=at, grace_s=900), START)
    # Ann is away when it falls due: the reminder waits for her.
    assert agenda.due(at, None) == []
    assert agenda.due(at + 10 * MIN, "bob") == []
    (due,) = agenda.due(at + 15 * MIN, "ann")
    agenda.delivered(due, at + 15 * MIN)
    assert agenda.missed_log("ann") == []


def test_a_user_away_beyond_grace_gets_a_missed_record_once(agenda: Agenda) -> None:
    at = START + timedelta(hours=1)
    item = agenda.add(event(cron="0 10 * * *", grace_s=600), START)
    assert agenda.due(at, None) == []
    assert agenda.due(at + 10 * MIN, None) == []
    # One second past the grace time: the call records the miss.
    assert agenda.due(at + 10 * MIN + S, "ann") == []
    assert agenda.due(at + 20 * MIN, "ann") == []
    (missed,) = agenda.missed_log("ann")
    assert (missed.item_id, missed.fire_time, missed.count) == (item.item_id, at, 1)
    assert "grace" in missed.reason
    # The next day's occurrence is scheduled and due as usual.
    (next_day,) = agenda.due(at + timedelta(days=1), "ann")
    assert next_day.fire_time == at + timedelta(days=1)
    assert len(agenda.missed_log("ann")) == 1


def test_an_occurrence_superseded_by_the_next_one_is_missed(agenda: Agenda) -> None:
    agenda.add(reminder(every=300, grace_s=3600), START)
    assert agenda.due(START + 5 * MIN, None) == []
    (due,) = agenda.due(START + 10 * MIN, "ann")
    assert due.fire_time == START + 10 * MIN
    (missed,) = agenda.missed_log("ann")
    assert missed.fire_time == START + 5 * MIN and "next occurrence" in missed.reason


def test_restart_delivers_within_grace_and_records_beyond_it_never_twice(db_url: str) -> None:
    first = Agenda.open(db_url)
    soon = first.add(reminder(at=START + timedelta(hours=1), grace_s=1800), START)
    early = first.add(reminder(at=START + timedelta(minutes=30), text="Pills", grace_s=600), START)
    daily = first.add(event(cron="0 8 * * *", grace_s=600), START)
    first.close()  # the daemon stops at 09:00 ...

    back = START + timedelta(hours=1, minutes=20)  # ... and starts again at 10:20
    second = Agenda.open(db_url)
    waiting = second.recover(back)
    assert [w.item_id for w in waiting] == [soon.item_id]
    missed = second.missed_log("ann")
    assert [(m.item_id, m.fire_time) for m in missed] == [
        (early.item_id, START + timedelta(minutes=30))
    ]
    assert "daemon was down" in missed[0].reason
    (due,) = second.due(back, "ann")
    second.delivered(due, back)
    second.close()

    third = Agenda.open(db_url)
    assert third.recover(back + MIN) == []
    assert third.due(back + MIN, "ann") == []
    assert len(third.missed_log("ann")) == 1
    assert [h.item_id for h in third.history("ann", Outcome.DELIVERED)] == [soon.item_id]
    upcoming = {u.item_id: u for u in third.upcoming("ann", back)}
    assert set(upcoming) == {daily.item_id}
    assert upcoming[daily.item_id].next_fire == datetime(2026, 11, 24, 8, 0, tzinfo=UTC)
    third.close()


def test_a_long_outage_is_one_missed_run_with_its_count(db_url: str) -> None:
    first = Agenda.open(db_url)
    item = first.add(reminder(every=60, grace_s=0), START)
    first.close()
    second = Agenda.open(db_url)
    later = START + timedelta(days=1)
    second.recover(later + 30 * S)
    (run,) = second.missed_log("ann")
    assert run.item_id == item.item_id
    assert run.fire_time == START + MIN
    assert run.last_fire_time == later
    assert run.count == 24 * 60
    (nxt,) = second.upcoming("ann", later + 30 * S)
    assert nxt.next_fire == later + MIN
    second.close()


def test_missed_records_written_late_survive_a_crash_as_one_record(db_url: str) -> None:
    first = Agenda.open(db_url)
    first.add(reminder(at=START + MIN, grace_s=0), START)
    assert first.due(START + 2 * MIN, None) == []  # missed, queued, not yet written
    # The process dies without close(): a new agenda finds the miss again.
    second = Agenda.open(db_url)
    second.recover(START + 3 * MIN)
    assert [m.count for m in second.missed_log("ann")] == [1]
    first.close()  # the late writer finds it already logged and does not duplicate it
    assert _rows(db_url, "agenda_occurrences") == 1
    second.close()


def test_remove_forgets_the_item_but_keeps_its_log(agenda: Agenda) -> None:
    item = agenda.add(reminder(at=START + MIN, grace_s=0), START)
    agenda.due(START + 2 * MIN, None)
    agenda.remove(item.item_id)
    assert agenda.upcoming("ann", START) == []
    assert len(agenda.missed_log("ann")) == 1
    with pytest.raises(AgendaNotFound) as error:
        agenda.remove(item.item_id)
    assert isinstance(error.value, KeyError)
    assert str(error.value) == f"no agenda item {item.item_id}"


def test_a_perceived_user_gets_items_added_and_removed_elsewhere(db_url: str) -> None:
    daemon = Agenda.open(db_url)
    kept = daemon.add(reminder(at=START + timedelta(hours=2)), START)
    cli = Agenda.open(db_url)
    added = cli.add(reminder(at=START + timedelta(hours=1), text="Call Bea"), START)
    cli.remove(kept.item_id)
    cli.close()
    assert daemon.due(START + timedelta(hours=1), "ann") == []  # not loaded yet
    daemon.user_perceived("ann", START + timedelta(hours=1))
    (due,) = daemon.due(START + timedelta(hours=1), "ann")
    assert due.item_id == added.item_id
    # The item removed by the other process does not fire at 11:00.
    assert daemon.due(START + timedelta(hours=2), "ann") == []
    assert [m.item_id for m in daemon.missed_log("ann")] == [added.item_id]
    daemon.close()


def test_upcoming_lists_next_fire_times_sorted_and_limited(agenda: Agenda) -> None:
    agenda.add(event(cron="0 10 * * MON", tz="Europe/Madrid"), START + MIN)
    agenda.add(reminder(at=datetime(2026, 11, 23, 16, 45), tz="Europe/Madrid"), START)
    agenda.add(reminder(user_id="bob", every=3600), START)
    items = agenda.upcoming(None, START)
    assert [u.next_fire for u in items] == [
        START + timedelta(hours=1),
        datetime(2026, 11, 23, 15, 45, tzinfo=UTC),
        datetime(2026, 11, 30, 9, 0, tzinfo=UTC),
    ]
    assert [u.user_id for u in agenda.upcoming("ann", START)] == ["ann", "ann"]
    assert len(agenda.upcoming(None, START, limit=1)) == 1
    shown = items[1].to_json()
    assert shown["next_fire"] == "2026-11-23T15:45:00.000Z"
    assert shown["next_fire_local"] == "2026-11-23T16:45:00+01:00"


BAD: list[tuple[dict[str, Any], str]] = [
    ({"user_id": ""}, "invalid user id"),
    ({"user_id": "ann\nsmith"}, "invalid user id"),
    ({"user_id": "ann/smith"}, "invalid user id"),
    ({"user_id": " ann"}, "invalid user id"),
    ({"kind": "event", "text": None}, "needs an activity"),
    ({"kind": "event", "text": None, "activity": "juggling"}, "unknown activity"),
    ({"kind": "event", "activity": "quiz"}, "has no text"),
    ({"activity": "quiz"}, "not an activity"),
    ({"text": "   "}, "needs a text"),
    ({"text": "x" * 501}, "at most 500"),
    ({"at": None}, "exactly one of"),
    ({"cron": "0 10 * * *"}, "exactly one of"),
    ({"at": None, "cron": "0 10 * *"}, "expected 5 fields"),
    ({"at": None, "cron": "61 10 * * *"}, "invalid cron expression"),
    ({"at": None, "cron": "0 10 * * 9"}, "bad weekday"),
    ({"at": None, "cron": "0 0 31 2 *"}, "never fires"),
    ({"at": None, "every": 0}, "every must be"),
    ({"at": None, "every": 600, "lead_s": 600}, "shorter than the interval"),
    ({"at": None, "cron": "*/5 * * * *", "lead_s": 600}, "shorter than the time"),
    ({"at": datetime(2026, 11, 22, 9, 0)}, "in the past"),
    ({"at": datetime(2027, 3, 28, 2, 30), "tz": "Europe/Madrid"}, "does not exist"),
    ({"tz": "Mars/Olympus"}, "unknown time zone"),
    ({"tz": "../etc/passwd"}, "unknown time zone"),
    ({"lead_s": -1}, "lead_s"),
    ({"grace_s": 10**9}, "grace_s"),
]


@pytest.mark.parametrize(("change", "message"), BAD)
def test_bad_input_is_one_line_and_stores_nothing(
    agenda: Agenda, db_url: str, change: dict[str, Any], message: str
) -> None:
    fields: dict[str, Any] = {
        "user_id": "ann",
        "kind": "reminder",
        "text": "Doctor",
        "at": START + timedelta(hours=1),
    }
    fields.update(change)
    with pytest.raises(AgendaError, match=message) as error:
        agenda.add(ItemSpec(**fields), START)
    assert "\n" not in str(error.value)
    assert agenda.upcoming(None, START) == []
    assert _rows(db_url, "agenda_items") == 0


def test_unknown_user_is_refused_when_the_profile_store_says_so(db_url: str) -> None:
    known = {"ann"}
    agenda = Agenda.open(db_url, user_exists=known.__contains__)
    agenda.add(reminder(at=START + MIN), START)
    with pytest.raises(AgendaError, match="unknown user 'zoe'"):
        agenda.add(reminder(user_id="zoe", at=START + MIN), START)
    assert [u.user_id for u in agenda.upcoming(None, START)] == ["ann"]
    agenda.close()


def test_spec_from_data_turns_type_errors_into_one_line(agenda: Agenda) -> None:
    with pytest.raises(AgendaError, match="kind"):
        ItemSpec.from_data({"user_id": "ann", "kind": "party"})
    with pytest.raises(AgendaError, match="every"):
        ItemSpec.from_data({"user_id": "ann", "kind": "reminder", "every": "often"})
    with pytest.raises(AgendaError, match="every"):
        ItemSpec.from_data({"user_id": "ann", "kind": "reminder", "every": True})
    with pytest.raises(AgendaError, match="colour"):
        ItemSpec.from_data({"user_id": "ann", "kind": "reminder", "colour": "red"})


def test_fresh_database_is_created_at_head_and_an_old_one_is_refused(
    tmp_path: Path, db_url: str
) -> None:
    assert not migrations.is_current(db_url)
    Agenda.open(db_url).close()
    assert migrations.is_current(db_url)
    old = tmp_path / "old.db"
    with sqlite3.connect(old) as connection:
        connection.execute("CREATE TABLE alembic_version_agenda (version_num VARCHAR(32))")
        connection.execute("INSERT INTO alembic_version_agenda VALUES ('agenda_0001')")
    with pytest.raises(AgendaError, match="dms db upgrade"):
        Agenda.open(f"sqlite:///{old}")


def test_a_database_that_cannot_be_opened_is_one_line(tmp_path: Path) -> None:
    for url in ("not a url", "nosuch://x", f"sqlite:///{tmp_path / 'file' / 'x.db'}"):
        if url.startswith("sqlite"):
            (tmp_path / "file").write_text("a file where a folder should be")
        with pytest.raises(AgendaError, match="cannot open the agenda") as error:
            Agenda.open(url)
        assert "\n" not in str(error.value)


def test_the_agenda_shares_the_database_with_other_alembic_histories(db_url: str) -> None:
    path = db_url.removeprefix("sqlite:///")
    with sqlite3.connect(path) as connection:
        connection.execute("CREATE TABLE alembic_version_memory (version_num VARCHAR(32))")
        connection.execute("INSERT INTO alembic_version_memory VALUES ('memory_0001')")
        connection.execute("CREATE TABLE profiles (id TEXT)")
    agenda = Agenda.open(db_url)
    agenda.close()
    with sqlite3.connect(path) as connection:
        memory = connection.execute("SELECT version_num FROM alembic_version_memory").fetchall()
        ours = connection.execute("SELECT version_num FROM alembic_version_agenda").fetchall()
    assert memory == [("memory_0001",)]
    assert ours == [(migrations.head(),)]
