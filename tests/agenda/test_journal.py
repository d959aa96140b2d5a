"""The agenda's journal: a delivery the database has not taken survives a kill -9, and
the agenda's writes survive what the profile store's writer survives (a locked database,
a torn journal, a record refused for good).

A crash is simulated by opening a second :class:`Agenda` on the same files without
closing the first (what a restart after kill -9 sees); the database is made to refuse
writes by replacing the agenda's bulk write with one that fails.
"""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Iterator
from datetime import timedelta
from pathlib import Path
from typing import Any

import pytest
from sqlalchemy.exc import IntegrityError, OperationalError

import agenda.writer as writer
from agenda import Agenda, ItemSpec, Outcome
from memory.spool import read_spool
from tests.agenda.conftest import START

MIN = timedelta(minutes=1)


def reminder(**extra: Any) -> ItemSpec:
    fields: dict[str, Any] = {"user_id": "ann", "kind": "reminder", "text": "The doctor at five"}
    fields.update(extra)
    return ItemSpec(**fields)


def _locked(*_args: Any) -> set[int]:
    """The agenda's bulk write, failing as it does while another process holds the lock."""
    raise OperationalError("INSERT", {}, Exception("database is locked"))


@pytest.fixture
def database_down(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """Every write of the agenda's log fails as a locked database does, until the test ends."""
    with monkeypatch.context() as patch:
        patch.setattr(writer, "write_records", _locked)
        yield


def _journal(db_url: str) -> Path:
    path = writer.journal_path(db_url)
    assert path is not None
    return path


def test_a_delivery_is_journaled_before_delivered_returns_and_replayed_once(
    db_url: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    first = Agenda.open(db_url, journal=True)
    item = first.add(reminder(at=START + 10 * MIN, grace_s=1800), START)
    fire = START + 10 * MIN
    with monkeypatch.context() as patch:
        patch.setattr(writer, "write_records", _locked)
        (due,) = first.due(fire, "ann")
        first.delivered(due, fire)  # the write failed: only the journal has it
        lines = [json.loads(line) for line in _journal(db_url).read_text().splitlines()]
        assert [(e["item_id"], e["outcome"]) for e in lines] == [(item.item_id, "delivered")]
    # kill -9: `first` is never closed; the daemon starts again within the grace time
    second = Agenda.open(db_url, journal=True)
    assert second.recover(fire + MIN) == []
    assert second.due(fire + MIN, "ann") == []
    (delivered,) = second.history("ann", Outcome.DELIVERED)
    assert (delivered.item_id, delivered.fire_time) == (item.item_id, fire)
    second.close()
    assert not _journal(db_url).exists()  # replayed and marked done: nothing left
    third = Agenda.open(db_url, journal=True)
    assert third.recover(fire + 2 * MIN) == []
    assert len(third.history("ann")) == 1
    third.close()


def test_a_journal_replayed_twice_logs_each_occurrence_once(
    db_url: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The crash came after the database took the records but before they were marked done."""
    first = Agenda.open(db_url, journal=True)
    item = first.add(reminder(every=300, grace_s=3600), START)
    with monkeypatch.context() as patch:
        patch.setattr(writer, "write_records", _locked)
        for step in (1, 2):
            now = START + step * 5 * MIN
            (due,) = first.due(now, "ann")
            first.delivered(due, now)
        entries = [json.loads(line) for line in _journal(db_url).read_text().splitlines()]
    assert [e["outcome"] for e in entries] == ["delivered", "delivered"]
    first.close()  # the database took them, and the journal said so ...
    assert len(first.history("ann", Outcome.DELIVERED)) == 2
    assert not _journal(db_url).exists()
    # ... but say the crash came before that mark reached the disk
    _journal(db_url).write_text("".join(json.dumps(e) + "\n" for e in entries))

    second = Agenda.open(db_url, journal=True)
    assert [h.fire_time for h in second.history("ann")] == [START + 5 * MIN, START + 10 * MIN]
    (next_one,) = second.upcoming("ann", START + 11 * MIN)
    assert next_one.item_id == item.item_id
    assert next_one.next_fire == START + 15 * MIN  # the cursor ends where it did
    second.close()


def test_a_journal_the_database_will_not_take_at_start_still_holds_the_cursor(
    db_url: str, database_down: None
) -> None:
    first = Agenda.open(db_url, journal=True)
    fire = START + 10 * MIN
    first.add(reminder(at=fire, grace_s=1800), START)
    (due,) = first.due(fire, "ann")
    first.delivered(due, fire)
    # kill -9, and the database is still locked when the daemon starts again
    second = Agenda.open(db_url, journal=True)
    assert second.recover(fire + MIN) == []
    assert second.due(fire + MIN, "ann") == []
    assert len(read_spool(_journal(db_url)).pending) == 1  # kept for later


def test_a_torn_last_line_is_skipped(db_url: str) -> None:
    first = Agenda.open(db_url, journal=True)
    first.add(reminder(at=START + 10 * MIN), START)
    first.close()
    _journal(db_url).write_text('{"item_id": 1, "outco')
    second = Agenda.open(db_url, journal=True)
    assert second.history("ann") == []
    assert second.due(START + 10 * MIN, "ann") != []
    second.close()


def test_the_command_line_and_the_simulator_do_not_journal(db_url: str) -> None:
    agenda = Agenda.open(db_url)  # background=False: no journal unless asked
    agenda.add(reminder(at=START + 10 * MIN), START)
    (due,) = agenda.due(START + 10 * MIN, "ann")
    agenda.delivered(due, START + 10 * MIN)
    agenda.close()
    assert not _journal(db_url).exists()
    assert writer.journal_path("sqlite://") is None


class Reports:
    """The agenda writer's report lines, as the daemon gets them for ``dms/errors``."""

    def __init__(self) -> None:
        self.lines: list[tuple[str, str]] = []

    def __call__(self, key: str, line: str) -> None:
        self.lines.append((key, line))

    def having(self, text: str) -> list[str]:
        return [line for _key, line in self.lines if text in line]


def test_deliveries_wait_out_a_locked_database_and_land_when_it_is_free(db_url: str) -> None:
    """The same writer as the profile store's: while another process holds SQLite's lock
    the deliveries wait in the journal (one report for the outage, health degraded), and
    land in order when the lock is released, off the tick."""
    reports = Reports()
    agenda = Agenda.open(db_url, background=True, poll_s=None, report=reports)
    first = agenda.add(reminder(at=START + 10 * MIN, grace_s=1800), START)
    second = agenda.add(reminder(at=START + 11 * MIN, grace_s=1800), START)
    got = agenda.due(START + 11 * MIN, "ann")  # both claimed
    assert sorted(due.item_id for due in got) == [first.item_id, second.item_id]
    holder = sqlite3.connect(db_url.removeprefix("sqlite:///"), isolation_level=None)
    holder.execute("BEGIN EXCLUSIVE")  # another process writes: the agenda's writes wait
    try:
        for due in sorted(got, key=lambda due: due.item_id):
            agenda.delivered(due, START + 11 * MIN)
        assert not agenda.wait_idle(2.0)
        health = agenda.health
        assert health.status == "degraded" and health.pending == 2
        assert len(read_spool(_journal(db_url)).pending) == 2
        (outage,) = reports.having("failed, will retry")
        assert "database is locked" in outage and str(_journal(db_url)) in outage
    finally:
        holder.rollback()
        holder.close()
    assert agenda.wait_idle(30.0)
    assert agenda.health.status == "ok"
    assert [h.item_id for h in agenda.history("ann", Outcome.DELIVERED)] == [
        first.item_id,
        second.item_id,
    ]
    agenda.close()
    assert not _journal(db_url).exists()
    assert len(reports.having("failed, will retry")) == 1  # one line for the outage


def test_a_torn_journal_line_is_kept_aside_and_reported_and_the_start_goes_on(
    db_url: str,
) -> None:
    first = Agenda.open(db_url, journal=True)
    item = first.add(reminder(at=START + 10 * MIN, grace_s=1800), START)
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(writer, "write_records", _locked)
        (due,) = first.due(START + 10 * MIN, "ann")
        first.delivered(due, START + 10 * MIN)
    journal = _journal(db_url)
    with journal.open("ab") as out:  # the kill -9 came in the middle of the next line
        out.write(b'{"item_id": 1, "outco')
    reports = Reports()
    second = Agenda.open(db_url, journal=True, report=reports)
    assert second.due(START + 11 * MIN, "ann") == []  # the kept delivery was replayed
    (kept,) = reports.having("unreadable line(s)")
    assert str(journal.with_name(journal.name + ".bad")) in kept
    assert journal.with_name(journal.name + ".bad").read_bytes() == b'{"item_id": 1, "outco\n'
    assert [h.item_id for h in second.history("ann", Outcome.DELIVERED)] == [item.item_id]
    second.close()


def test_a_record_the_database_refuses_is_quarantined_and_the_others_land(
    db_url: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A batch refused as a whole is written again one record at a time: only the
    refused record is set aside (in the quarantine file, with a report)."""
    reports = Reports()
    agenda = Agenda.open(db_url, journal=True, report=reports)
    kept = agenda.add(reminder(at=START + 10 * MIN, grace_s=1800), START)
    refused = agenda.add(reminder(at=START + 10 * MIN, grace_s=1800, text="Bad"), START)
    real = writer.write_records

    def refusing(connection: Any, entries: list[dict[str, Any]]) -> set[int]:
        if any(entry["item_id"] == refused.item_id for entry in entries):
            raise IntegrityError("INSERT", {}, Exception("CHECK constraint failed"))
        return real(connection, entries)

    monkeypatch.setattr(writer, "write_records", refusing)
    got = agenda.due(START + 10 * MIN, "ann")
    assert {due.item_id for due in got} == {kept.item_id, refused.item_id}
    with monkeypatch.context() as patch:
        patch.setattr(writer, "write_records", _locked)
        for due in got:
            agenda.delivered(due, START + 10 * MIN)  # both journaled, one batch later
    agenda.upcoming("ann", START + 10 * MIN)  # flushes
    assert [h.item_id for h in agenda.history("ann")] == [kept.item_id]
    (line,) = reports.having("refused")
    assert f"agenda item {refused.item_id}" in line and "agenda-quarantine" in line
    quarantine = writer.quarantine_path(db_url)
    assert quarantine is not None
    (entry,) = [json.loads(text) for text in quarantine.read_text().splitlines()]
    assert entry["item_id"] == refused.item_id and "constraint" in entry["error"]
    agenda.close()
    assert not _journal(db_url).exists()
