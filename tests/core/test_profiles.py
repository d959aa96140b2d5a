"""The controller's ProfileService through a real database outage: cached profiles are
served, each failure is reported in one line, writes wait in order and none is lost."""

from __future__ import annotations

from collections.abc import Iterator
from datetime import UTC, datetime, timedelta
from pathlib import Path

import pytest
from sqlalchemy import text

from dms.profiles import RETRY_EVERY_S, ProfileService
from memory import ProfileStore

NOW = datetime(2026, 11, 23, 10, 0, tzinfo=UTC)
LATER = NOW + timedelta(seconds=RETRY_EVERY_S)


class Outage:
    """Takes the ``users`` table away, which every profile read and write needs."""

    def __init__(self, store: ProfileStore) -> None:
        self.store = store

    def begin(self) -> None:
        with self.store.engine.begin() as connection:
            connection.execute(text("ALTER TABLE users RENAME TO users_away"))

    def end(self) -> None:
        with self.store.engine.begin() as connection:
            connection.execute(text("ALTER TABLE users_away RENAME TO users"))


@pytest.fixture
def store(tmp_path: Path) -> Iterator[ProfileStore]:
    profiles = ProfileStore(f"sqlite:///{tmp_path / 'dms.db'}")
    yield profiles
    profiles.close()


@pytest.fixture
def reports() -> list[tuple[str, str]]:
    return []


@pytest.fixture
def service(store: ProfileStore, reports: list[tuple[str, str]]) -> ProfileService:
    return ProfileService(store, lambda key, line: reports.append((key, line)))


def test_an_outage_serves_the_cached_profile_and_reports_one_line(
    service: ProfileService, store: ProfileStore, reports: list[tuple[str, str]]
) -> None:
    loaded = service.load("ann", NOW)
    assert loaded is not None and loaded.user_id == "ann"
    Outage(store).begin()
    assert service.load("ann", NOW) == loaded
    assert service.cached("ann") == loaded
    assert service.load("bob", NOW) is None  # never loaded: nothing to serve
    assert [key for key, _ in reports] == ["memory", "memory"]
    first = reports[0][1]
    assert "\n" not in first
    assert first.startswith("cannot load profile ann: database error:")
    assert "no such table: users" in first


def test_writes_wait_in_order_during_an_outage_and_none_is_lost(
    service: ProfileService, store: ProfileStore, reports: list[tuple[str, str]]
) -> None:
    service.load("ann", NOW)
    outage = Outage(store)
    outage.begin()
    assert service.call("record_feedback", "ann", "quiz", 0.25, NOW) is None
    assert service.call("update", "ann", NOW, name="Ann") is None
    assert service.call("record_feedback", "ann", "quiz", 0.75, NOW + timedelta(seconds=1)) is None
    assert service.call("update", "ann", NOW, name="Anna") is None
    assert service.pending_writes == 4
    # One line for the outage; the writes behind the first one queue up silently.
    ((key, line),) = reports
    assert key == "memory" and "\n" not in line
    assert line.startswith("record_feedback failed, will retry: database error:")
    assert "no such table: users" in line
    service.retry(NOW)  # still down: everything stays queued, nothing more is reported
    assert service.pending_writes == 4 and len(reports) == 1
    outage.end()
    service.retry(NOW + timedelta(seconds=1))  # too soon after the last try
    assert service.pending_writes == 4
    service.retry(LATER + timedelta(seconds=1))
    assert service.pending_writes == 0
    exported = store.export("ann")
    assert [f["score"] for f in exported["feedback"]] == [0.25, 0.75]
    assert exported["profile"]["name"] == "Anna"  # the later update wins
    assert exported["profile"]["scores"]["quiz"]["feedback_count"] == 2


def test_a_write_after_the_outage_comes_after_the_queued_ones(
    service: ProfileService, store: ProfileStore
) -> None:
    service.load("ann", NOW)
    outage = Outage(store)
    outage.begin()
    service.call("update", "ann", NOW, name="Old")
    outage.end()
    # The store is back before the retry is due: the new write must not be overtaken.
    profile = service.call("update", "ann", NOW, name="New")
    assert profile is not None and profile.name == "New"
    assert service.pending_writes == 0
    service.retry(LATER + timedelta(seconds=1))
    assert store.get("ann").name == "New"
    assert service.cached("ann") == store.get("ann")


def test_a_refused_write_is_reported_and_not_queued(
    service: ProfileService, reports: list[tuple[str, str]]
) -> None:
    service.load("ann", NOW)
    assert service.call("record_feedback", "ann", "quiz", 7.0, NOW) is None
    assert service.pending_writes == 0
    ((key, line),) = reports
    assert key == "memory" and line.startswith("record_feedback refused: score:")


def test_a_full_outbox_says_which_write_it_loses(
    store: ProfileStore, reports: list[tuple[str, str]]
) -> None:
    service = ProfileService(store, lambda key, line: reports.append((key, line)), outbox_size=2)
    service.load("ann", NOW)
    Outage(store).begin()
    service.call("record_feedback", "ann", "quiz", 0.5, NOW)
    service.call("record_answer", "ann", "q1", "yes", NOW)
    service.call("record_feedback", "ann", "jokes", 1.0, NOW)
    assert reports[-1] == ("memory", "outbox full: the oldest queued record_feedback is lost")
    assert service.pending_writes == 2
    Outage(store).end()
    service.retry(LATER)
    scores = store.get("ann").scores
    assert "jokes" in scores and "quiz" not in scores  # the lost write is the oldest one
