"""Robots sharing one agenda: each occurrence delivered once, by one robot; items added
anywhere reach every robot without a restart.

Each robot is an :class:`agenda.Agenda` of its own on one database (its own engine and
claimer id), as each daemon of a fleet holds one.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from datetime import timedelta
from typing import Any

import pytest
from sqlalchemy.exc import OperationalError

import agenda.claims as claims
import agenda.writer as writer
from agenda import Agenda, DueItem, ItemSpec, Outcome
from tests.fleet.conftest import NOW

MIN = timedelta(minutes=1)
ROUNDS = 50


def reminder(at_minutes: int, **extra: Any) -> ItemSpec:
    fields: dict[str, Any] = {
        "user_id": "ann",
        "kind": "reminder",
        "text": f"Reminder {at_minutes}",
        "at": NOW + at_minutes * MIN,
        "grace_s": 30,
    }
    fields.update(extra)
    return ItemSpec(**fields)


@contextmanager
def robots(url: str, count: int = 2, **options: Any) -> Iterator[list[Agenda]]:
    opened = [Agenda.open(url, claimer=f"robot{index}", **options) for index in range(count)]
    try:
        yield opened
    finally:
        for agenda in opened:
            agenda.close()


def _at_once(jobs: list[Callable[[], Any]]) -> list[Any]:
    """Run ``jobs`` on threads of their own released together; their results in order."""
    start = threading.Barrier(len(jobs))
    results: list[Any] = [None] * len(jobs)
    errors: list[BaseException] = []

    def run(index: int) -> None:
        try:
            start.wait()
            results[index] = jobs[index]()
        except BaseException as error:
            errors.append(error)

    threads = [threading.Thread(target=run, args=(index,)) for index in range(len(jobs))]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(60)
    assert not any(thread.is_alive() for thread in threads), "a robot is stuck"
    assert not errors, errors
    return results


def test_two_robots_seeing_ann_in_the_same_second_deliver_each_reminder_once(
    pg_url: str,
) -> None:
    """50 times: a reminder falls due while robots A and B both see Ann; both ask what is
    due at the same instant, on threads of their own: exactly one gets it."""
    with robots(pg_url, background=True) as (a, b):
        items = [a.add(reminder(minute + 1), NOW) for minute in range(ROUNDS)]
        b.user_perceived("ann", NOW)
        assert b.upcoming("ann", NOW, limit=ROUNDS + 1)[-1].item_id == items[-1].item_id
        winners: list[str] = []
        for minute, item in enumerate(items, start=1):
            now = NOW + minute * MIN
            first = _at_once([lambda r=r, t=now: r.due(t, "ann") for r in (a, b)])
            assert a.wait_idle(30) and b.wait_idle(30)  # both claims have landed
            again = [a.due(now, "ann"), b.due(now, "ann")]
            got = {
                name: [due.item_id for due in dues]
                for name, dues in zip("abab", first + again, strict=True)
                if dues
            }
            assert list(got.values()) == [[item.item_id]], (minute, first, again)
            (name,) = got
            winner, loser = (a, b) if name == "a" else (b, a)
            (due,) = winner.due(now, "ann")
            winner.delivered(due, now)
            winners.append(name)
            # The other robot never returns it, later in its grace time either.
            assert loser.due(now + timedelta(seconds=10), "ann") == []
        for robot in (a, b):  # each records misses of what the other one delivered ...
            robot.due(NOW + (ROUNDS + 2) * MIN, None)
            robot.history("ann")  # ... and writes them: a delivery stays a delivery
        log = a.history("ann")
    assert [(o.item_id, o.outcome) for o in log] == [
        (item.item_id, Outcome.DELIVERED) for item in items
    ]
    assert a.claims_lost + b.claims_lost == ROUNDS


def test_a_claim_is_made_once_by_one_of_two_robots_claiming_at_once(fleet_url: str) -> None:
    with robots(fleet_url) as (a, b):
        for minute in range(1, 21):
            item = a.add(reminder(minute), NOW)
            due = DueItem(
                item_id=item.item_id,
                user_id="ann",
                kind=item.kind,
                activity=None,
                text=item.text,
                priority=item.priority,
                fire_time=NOW + minute * MIN,
                due_at=NOW + minute * MIN,
            )
            now = NOW + minute * MIN
            won = _at_once([lambda r=r, d=due, t=now: r.claim(d, t) for r in (a, b)])
            assert sorted(won) == [False, True]
            winner = a if won[0] else b
            assert winner.claim(due, NOW + minute * MIN)  # its own claim is still its own


def test_a_robot_restarted_after_its_claim_delivers_what_it_claimed(fleet_url: str) -> None:
    with robots(fleet_url) as (a, b):
        item = a.add(reminder(1), NOW)
        b.user_perceived("ann", NOW)
        (due,) = a.due(NOW + MIN, "ann")  # a claims it ... and dies before delivering
        assert b.due(NOW + MIN, "ann") == []
    with robots(fleet_url) as (a_again, b_again):
        (due,) = a_again.due(NOW + MIN + 5 * timedelta(seconds=1), "ann")
        assert due.item_id == item.item_id
        assert b_again.due(NOW + MIN + 5 * timedelta(seconds=1), "ann") == []


def test_an_occurrence_its_claimer_never_delivers_is_recorded_missed(fleet_url: str) -> None:
    with robots(fleet_url) as (a, b):
        a.add(reminder(1), NOW)
        b.user_perceived("ann", NOW)
        assert len(a.due(NOW + MIN, "ann")) == 1  # claimed; then robot a is gone for good
        assert b.due(NOW + MIN, "ann") == []
        b.due(NOW + 2 * MIN, "ann")  # past the grace time: b records it missed
        (missed,) = b.history("ann")
        assert missed.outcome == Outcome.MISSED


def test_a_delivery_replaces_another_robots_miss_of_it(fleet_url: str) -> None:
    """Both robots saw Ann; robot a claimed and delivered her reminder, robot b gave up
    on it (its grace time ended) and wrote it missed before robot a could write its
    delivery: the log says delivered."""
    with robots(fleet_url) as (a, b):
        item = a.add(reminder(1), NOW)
        b.user_perceived("ann", NOW)
        with _database_down_for(a):
            (due,) = a.due(NOW + MIN, "ann")
            assert b.due(NOW + MIN, "ann") == []  # a has it
            a.delivered(due, NOW + MIN)  # journaled in memory: its write failed
        b.due(NOW + 2 * MIN, "ann")
        assert [o.outcome for o in b.history("ann")] == [Outcome.MISSED]
        assert [(o.item_id, o.outcome) for o in a.history("ann")] == [
            (item.item_id, Outcome.DELIVERED)
        ]


@contextmanager
def _database_down_for(agenda: Agenda) -> Iterator[None]:
    """Every write of ``agenda``'s log fails (as a locked or absent database does)."""
    real = writer.write_records

    def failing(connection: Any, entries: list[dict[str, Any]]) -> set[int]:
        if connection.engine is agenda._engine:
            raise OperationalError("INSERT", {}, Exception("database is locked"))
        return real(connection, entries)

    writer.write_records = failing  # type: ignore[assignment]
    try:
        yield
    finally:
        writer.write_records = real  # type: ignore[assignment]


def test_items_added_elsewhere_reach_a_robot_without_a_restart(fleet_url: str) -> None:
    """An item added by another robot or the command line, for a user this robot is
    already serving, comes out of due() after a poll: no restart, no new perception."""
    with robots(fleet_url, count=1, poll_s=10) as (a,):
        a.user_perceived("ann", NOW)
        assert a.due(NOW, "ann") == []
        cli = Agenda.open(fleet_url)
        item = cli.add(reminder(1), NOW)
        cli.close()
        assert a.due(NOW + 5 * timedelta(seconds=1), "ann") == []  # not polled yet
        a.due(NOW + 10 * timedelta(seconds=1), "ann")  # the poll
        (due,) = a.due(NOW + MIN, "ann")
        assert due.item_id == item.item_id


@pytest.mark.parametrize("offline", [False, True])
def test_without_the_database_a_claim_waits_or_the_item_is_delivered_offline(
    fleet_url: str, offline: bool
) -> None:
    """A server database that cannot be reached holds the reminder until the claim can
    be made (never twice); with ``offline_delivery`` (a SQLite file's default) it is
    delivered anyway."""
    with robots(fleet_url, count=1, offline_delivery=offline) as (a,):
        item = a.add(reminder(1), NOW)
        real = claims.claim_occurrence

        def unreachable(*_: Any) -> str:
            raise OperationalError("INSERT", {}, Exception("connection refused"))

        claims.claim_occurrence = unreachable  # type: ignore[assignment]
        try:
            got = a.due(NOW + MIN, "ann")
            assert [due.item_id for due in got] == ([item.item_id] if offline else [])
            retry = NOW + MIN + timedelta(seconds=claims.CLAIM_RETRY_S)
        finally:
            claims.claim_occurrence = real  # type: ignore[assignment]
        if not offline:
            assert a.due(NOW + MIN + timedelta(seconds=1), "ann") == []  # no retry yet
            (due,) = a.due(retry, "ann")  # the database is back
            assert due.item_id == item.item_id


def test_in_a_fleet_a_miss_is_written_by_a_robot_that_saw_the_user(fleet_url: str) -> None:
    """Every robot holds every item; only one that saw Ann since her reminder fell due
    writes its miss (not each robot of the fleet again). When nobody saw her, the robot
    that next sees her finds the miss from the cursor in the database and writes it."""
    with robots(fleet_url, unseen_misses=False) as (a, b):
        first = a.add(reminder(1, every=3600, at=None), NOW - 59 * MIN)
        b.user_perceived("ann", NOW - 59 * MIN)
        a.due(NOW + 2 * MIN, None)  # ann was nowhere: neither robot writes the miss
        b.due(NOW + 2 * MIN, None)
        assert a.history("ann") == b.history("ann") == []
        a.user_perceived("ann", NOW + 3 * MIN)  # robot a sees her: it writes it
        (missed,) = a.history("ann")
        assert (missed.item_id, missed.outcome, missed.fire_time) == (
            first.item_id,
            Outcome.MISSED,
            NOW + MIN,
        )
        got = b.due(NOW + 61 * MIN, "ann")  # b saw her at the next one: it is hers to claim
        assert [due.fire_time for due in got] == [NOW + 61 * MIN]
