"""The agenda's journal: a delivery the database has not taken survives a kill -9.

A crash is simulated by opening a second :class:`Agenda` on the same files without
closing the first (what a restart after kill -9 sees); the database is made to refuse
writes by replacing the agenda's bulk write with one that fails.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from datetime import timedelta
from pathlib import Path
from typing import Any

import pytest
from sqlalchemy.exc import OperationalError

import agenda.service as service
from agenda import Agenda, ItemSpec, Outcome
from memory.spool import Spool
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
        patch.setattr(service, "_write", _locked)
        yield


def _journal(db_url: str) -> Path:
    path = service.journal_path(db_url)
    assert path is not None
    return path


def test_a_delivery_is_journaled_before_delivered_returns_and_replayed_once(
    db_url: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    first = Agenda(db_url, journal=True)
    item = first.add(reminder(at=START + 10 * MIN, grace_s=1800), START)
    fire = START + 10 * MIN
    with monkeypatch.context() as patch:
        patch.setattr(service, "_write", _locked)
        (due,) = first.due(fire, "ann")
        first.delivered(due, fire)  # the write failed: only the journal has it
        lines = [json.loads(line) for line in _journal(db_url).read_text().splitlines()]
        assert [(e["item_id"], e["outcome"]) for e in lines] == [(item.item_id, "delivered")]
    # kill -9: `first` is never closed; the daemon starts again within the grace time
    second = Agenda(db_url, journal=True)
    assert second.recover(fire + MIN) == []
    assert second.due(fire + MIN, "ann") == []
    (delivered,) = second.history("ann", Outcome.DELIVERED)
    assert (delivered.item_id, delivered.fire_time) == (item.item_id, fire)
    second.close()
    assert not _journal(db_url).exists()  # replayed and marked done: nothing left
    third = Agenda(db_url, journal=True)
    assert third.recover(fire + 2 * MIN) == []
    assert len(third.history("ann")) == 1
    third.close()


def test_a_journal_replayed_twice_logs_each_occurrence_once(db_url: str) -> None:
    """The crash came after the database took the records but before they were marked done."""
    first = Agenda(db_url, journal=True)
    item = first.add(reminder(every=300, grace_s=3600), START)
    for step in (1, 2):
        now = START + step * 5 * MIN
        (due,) = first.due(now, "ann")
        first.delivered(due, now)
    entries = [json.loads(line) for line in _journal(db_url).read_text().splitlines() if line]
    first.close()
    assert len(first.history("ann", Outcome.DELIVERED)) == 2
    _journal(db_url).write_text("".join(json.dumps(e) + "\n" for e in entries))

    second = Agenda(db_url, journal=True)
    assert [h.fire_time for h in second.history("ann")] == [START + 5 * MIN, START + 10 * MIN]
    (next_one,) = second.upcoming("ann", START + 11 * MIN)
    assert next_one.item_id == item.item_id
    assert next_one.next_fire == START + 15 * MIN  # the cursor ends where it did
    second.close()


def test_a_journal_the_database_will_not_take_at_start_still_holds_the_cursor(
    db_url: str, database_down: None
) -> None:
    first = Agenda(db_url, journal=True)
    fire = START + 10 * MIN
    first.add(reminder(at=fire, grace_s=1800), START)
    (due,) = first.due(fire, "ann")
    first.delivered(due, fire)
    # kill -9, and the database is still locked when the daemon starts again
    second = Agenda(db_url, journal=True)
    assert second.recover(fire + MIN) == []
    assert second.due(fire + MIN, "ann") == []
    assert len(Spool(_journal(db_url)).pending) == 1  # kept for later


def test_a_torn_last_line_is_skipped(db_url: str) -> None:
    first = Agenda(db_url, journal=True)
    first.add(reminder(at=START + 10 * MIN), START)
    first.close()
    _journal(db_url).write_text('{"item_id": 1, "outco')
    second = Agenda(db_url, journal=True)
    assert second.history("ann") == []
    assert second.due(START + 10 * MIN, "ann") != []
    second.close()


def test_the_command_line_and_the_simulator_do_not_journal(db_url: str) -> None:
    agenda = Agenda(db_url)  # background=False: no journal unless asked
    agenda.add(reminder(at=START + 10 * MIN), START)
    (due,) = agenda.due(START + 10 * MIN, "ann")
    agenda.delivered(due, START + 10 * MIN)
    agenda.close()
    assert not _journal(db_url).exists()
    assert service.journal_path("sqlite://") is None
