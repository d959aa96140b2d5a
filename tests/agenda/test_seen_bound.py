"""Who the agenda saw is bounded: a flood of distinct user ids neither grows the daemon
nor changes what is delivered, nor which misses this robot records for the users it
saw lately."""

from __future__ import annotations

from datetime import timedelta

from agenda import Agenda, ItemSpec, Outcome
from agenda.schedule import to_us
from agenda.seen import MAX_SEEN_USERS, SEEN_KEEP_S, US_PER_S, SeenUsers
from tests.agenda.conftest import START

MIN = timedelta(minutes=1)


def test_a_flood_of_ids_keeps_at_most_the_bound_the_most_recent_ones() -> None:
    seen = SeenUsers(bound=100)
    for index in range(10_000):
        seen.saw(f"visitor-{index}", index)
    assert len(seen) == 100
    assert seen.last("visitor-9999") == 9999
    assert seen.last("visitor-9900") == 9900
    assert seen.last("visitor-9899") is None


def test_seeing_a_user_again_keeps_them_and_never_moves_their_time_back() -> None:
    seen = SeenUsers(bound=3)
    seen.saw("ann", 50)
    seen.saw("bob", 10)
    seen.saw("ann", 20)  # an earlier time (a clock stepped back) keeps the later one
    seen.saw("cid", 30)
    seen.saw("dee", 40)  # over the bound: bob, the least recently seen, goes
    assert (seen.last("ann"), seen.last("bob"), len(seen)) == (50, None, 3)


def test_sightings_older_than_any_occurrence_could_need_are_dropped() -> None:
    seen = SeenUsers()
    seen.saw("ann", 0)
    seen.saw("bob", SEEN_KEEP_S * US_PER_S)
    assert seen.last("ann") == 0  # exactly at the horizon: kept
    seen.saw("cid", SEEN_KEEP_S * US_PER_S + 1)
    assert seen.last("ann") is None
    assert len(seen) == 2


def test_a_flood_of_present_ids_changes_no_delivery_and_no_recent_miss(db_url: str) -> None:
    agenda = Agenda.open(db_url, unseen_misses=False)
    try:
        at = START + timedelta(hours=1)
        bob = agenda.add(ItemSpec(user_id="bob", kind="reminder", text="Tea", at=at), START)
        ann = agenda.add(
            ItemSpec(user_id="ann", kind="reminder", text="Pills", at=at, grace_s=600), START
        )
        flood = 3 * MAX_SEEN_USERS
        for index in range(flood):
            now = START + timedelta(microseconds=index)
            assert agenda.due(now, f"visitor-{index}") == []
        assert len(agenda._seen) <= MAX_SEEN_USERS
        assert agenda.due(at, "ann") != []  # ann is seen once her reminder is due
        (due,) = agenda.due(at + MIN, "bob")
        assert due.item_id == bob.item_id
        agenda.delivered(due, at + MIN)
        for index in range(MAX_SEEN_USERS - 2):  # more visitors while ann's reminder waits
            agenda.due(at + MIN + timedelta(microseconds=index), f"other-{index}")
        assert len(agenda._seen) <= MAX_SEEN_USERS
        agenda.due(at + 11 * MIN, None)  # past ann's grace: this robot saw her, it records
        assert agenda._seen.last("ann") == to_us(at)
        history = agenda.history("ann")
        assert [(h.item_id, h.outcome) for h in history] == [(ann.item_id, Outcome.MISSED)]
    finally:
        agenda.close()
