"""Two robots writing one profile at once: the result is that of some serial order of
their writes, no increment is lost, and a write replayed with its id changes nothing.

Each robot is a :class:`memory.ProfileStore` of its own (its own engine) on one database,
a real SQLite file or the real PostgreSQL; each runs its writes in order on a thread of
its own, both released at once. The expected profiles are those of a pure model of the
writes, for every interleaving of the two robots' sequences.
"""

from __future__ import annotations

import itertools
import threading
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from memory import Profile, ProfileStore, proactivity
from memory.store import FAILURES_TO_SWITCH
from tests.fleet.conftest import NOW
from tests.postgres import POSTGRES_URL, fresh_schema

ACTIVITIES = ("quiz", "jokes")
SCORES = (0.0, 0.25, 0.5, 0.75, 1.0)  # exact in binary: a sum does not depend on the order

Op = tuple[Any, ...]

ops = st.one_of(
    st.tuples(st.just("feedback"), st.sampled_from(ACTIVITIES), st.sampled_from(SCORES)),
    st.tuples(
        st.just("activity"),
        st.sampled_from(ACTIVITIES),
        st.sampled_from(["completed", "cancelled", "interrupted"]),
    ),
    st.tuples(st.just("interaction"), st.sampled_from(["voice", "screen"]), st.booleans()),
    st.tuples(st.just("initiative"), st.booleans()),
    st.tuples(st.just("field"), st.sampled_from(["name", "favorite_room"]), st.sampled_from("AB")),
    st.tuples(st.just("attribute"), st.sampled_from(["hobby", "pet"]), st.sampled_from("AB")),
)
robot_ops = st.lists(ops, max_size=6)


@dataclass
class Model:
    """What the profile must be after a serial order of writes."""

    scores: dict[str, tuple[float, int, int, int]] = field(default_factory=dict)
    voice_failures: int = 0
    screen_failures: int = 0
    interaction_style: str = "voice"
    initiative: tuple[int, int] = (0, 0)
    proactivity: tuple[str, float] = ("unknown", 0.0)
    fields: dict[str, str] = field(default_factory=dict)
    attributes: dict[str, str] = field(default_factory=dict)

    def apply(self, op: Op) -> None:
        kind = op[0]
        if kind == "feedback":
            total, count, done, cancelled = self.scores.get(op[1], (0.0, 0, 0, 0))
            self.scores[op[1]] = (total + op[2], count + 1, done, cancelled)
        elif kind == "activity" and op[2] != "interrupted":
            total, count, done, cancelled = self.scores.get(op[1], (0.0, 0, 0, 0))
            if op[2] == "cancelled":
                cancelled += 1
            else:
                done += 1
            self.scores[op[1]] = (total, count, done, cancelled)
        elif kind == "interaction":
            self._interaction(op[1], op[2])
        elif kind == "initiative":
            taken, offered = proactivity.forget(
                self.initiative[0] + int(op[1]), self.initiative[1] + 1
            )
            self.initiative = (taken, offered)
            self.proactivity = proactivity.estimate(taken, offered, None, self.proactivity[0])
        elif kind == "field":
            self.fields[op[1]] = op[2]
        elif kind == "attribute":
            self.attributes[op[1]] = op[2]

    def _interaction(self, channel: str, answered: bool) -> None:
        name = f"{channel}_failures"
        if answered:
            setattr(self, name, 0)
            return
        failures = getattr(self, name) + 1
        setattr(self, name, failures)
        if failures >= FAILURES_TO_SWITCH and self.interaction_style == channel:
            self.interaction_style = "screen" if channel == "voice" else "voice"
            setattr(self, name, 0)

    def key(self) -> tuple[Any, ...]:
        return (
            tuple(sorted(self.scores.items())),
            self.voice_failures,
            self.screen_failures,
            self.interaction_style,
            self.initiative,
            self.proactivity,
            tuple(sorted(self.fields.items())),
            tuple(sorted(self.attributes.items())),
        )


def observed(profile: Profile) -> tuple[Any, ...]:
    """The stored profile in the model's terms."""
    scores = {
        name: (s.feedback_sum, s.feedback_count, s.completions, s.cancellations)
        for name, s in profile.scores.items()
    }
    fields = {
        name: value
        for name in ("name", "favorite_room")
        if (value := getattr(profile, name)) is not None
    }
    return (
        tuple(sorted(scores.items())),
        profile.voice_failures,
        profile.screen_failures,
        profile.interaction_style,
        (profile.initiative_taken, profile.initiative_offered),
        (profile.proactivity, profile.proactivity_confidence),
        tuple(sorted(fields.items())),
        tuple(sorted(profile.attributes.items())),
    )


def serial_results(first: list[Op], second: list[Op]) -> set[tuple[Any, ...]]:
    """The profile after every interleaving that keeps each robot's own order."""
    results = set()
    total = len(first) + len(second)
    for places in itertools.combinations(range(total), len(first)):
        model = Model()
        mine, theirs = iter(first), iter(second)
        chosen = set(places)
        for index in range(total):
            model.apply(next(mine) if index in chosen else next(theirs))
        results.add(model.key())
    return results


def write(store: ProfileStore, user: str, op: Op, write_id: str) -> None:
    """One robot's write, as the daemon makes it (with its unique id)."""
    kind = op[0]
    if kind == "feedback":
        store.record_feedback(user, op[1], op[2], NOW, write_id=write_id)
    elif kind == "activity":
        cancelled = op[2] == "cancelled"
        store.record_activity(user, op[1], NOW, NOW, op[2], "robot", cancelled, write_id=write_id)
    elif kind == "interaction":
        store.record_interaction(user, op[1], op[2], NOW, write_id=write_id)
    elif kind == "initiative":
        store.record_initiative(user, op[1], NOW, write_id=write_id)
    else:  # a field or a free attribute
        store.update(user, NOW, write_id=write_id, **{op[1]: op[2]})


def run_concurrently(
    stores: tuple[ProfileStore, ProfileStore], user: str, plans: tuple[list[Op], list[Op]]
) -> list[list[str]]:
    """Each robot meets ``user`` (a new one) and makes its writes on its own thread, both
    released at once. Returns the write ids of each robot."""
    ids = [[f"{uuid.uuid4().hex}" for _ in plan] for plan in plans]
    start = threading.Barrier(2)
    errors: list[BaseException] = []

    def robot(index: int) -> None:
        try:
            start.wait()
            stores[index].get_or_create(user, NOW)
            for op, write_id in zip(plans[index], ids[index], strict=True):
                write(stores[index], user, op, write_id)
        except BaseException as error:
            errors.append(error)

    threads = [threading.Thread(target=robot, args=(index,)) for index in (0, 1)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(60)
    assert not any(thread.is_alive() for thread in threads), "a robot is stuck"
    assert not errors, errors
    return ids


@contextmanager
def two_robots(url: str) -> Iterator[tuple[ProfileStore, ProfileStore]]:
    first = ProfileStore(url)
    second = ProfileStore(url)
    try:
        yield first, second
    finally:
        first.close()
        second.close()


def check_merge(
    stores: tuple[ProfileStore, ProfileStore], first: list[Op], second: list[Op]
) -> None:
    user = f"ann-{uuid.uuid4().hex[:8]}"
    ids = run_concurrently(stores, user, (first, second))
    profile = stores[0].get(user)
    assert observed(profile) in serial_results(first, second)
    # No increment lost: every feedback, completion and cancellation is counted.
    everything = first + second
    assert sum(s.feedback_count for s in profile.scores.values()) == sum(
        op[0] == "feedback" for op in everything
    )
    assert sum(s.completions + s.cancellations for s in profile.scores.values()) == sum(
        op[0] == "activity" and op[2] != "interrupted" for op in everything
    )
    chances = sum(op[0] == "initiative" for op in everything)
    assert chances <= 2 * proactivity.WINDOW  # so none was forgotten: each is counted
    assert profile.initiative_offered == chances
    history = stores[1].export(user)
    assert len(history["feedback"]) == sum(op[0] == "feedback" for op in everything)
    assert len(history["activities"]) == sum(op[0] == "activity" for op in everything)
    # A spool replayed after a crash brings every write again, with its id: nothing changes.
    for index, plan in enumerate((first, second)):
        for op, write_id in zip(plan, ids[index], strict=True):
            write(stores[1 - index], user, op, write_id)
    assert stores[0].get(user).model_dump(exclude={"updated_at"}) == profile.model_dump(
        exclude={"updated_at"}
    )
    assert len(stores[0].export(user)["feedback"]) == len(history["feedback"])


MERGE_SETTINGS = settings(
    max_examples=25,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)


@MERGE_SETTINGS
@given(first=robot_ops, second=robot_ops)
def test_two_robots_on_one_sqlite_file_merge_as_some_serial_order(
    tmp_path: Path, first: list[Op], second: list[Op]
) -> None:
    with two_robots(f"sqlite:///{tmp_path / 'fleet.db'}") as stores:
        check_merge(stores, first, second)


@pytest.fixture(scope="module")
def shared_postgres() -> Iterator[str]:
    if not POSTGRES_URL:
        pytest.skip("DMS_TEST_POSTGRES_URL is not set: no PostgreSQL server to share")
    with fresh_schema("merge") as url:
        yield url


@MERGE_SETTINGS
@given(first=robot_ops, second=robot_ops)
def test_two_robots_on_postgres_merge_as_some_serial_order(
    shared_postgres: str, first: list[Op], second: list[Op]
) -> None:
    with two_robots(shared_postgres) as stores:
        check_merge(stores, first, second)


def test_a_field_write_on_a_stale_read_is_retried_on_the_fresh_row(tmp_path: Path) -> None:
    """SQLite: robot A reads Ann's row; robot B writes other fields and commits; A's write
    finds the version moved, runs again on B's row and keeps B's fields."""
    with two_robots(f"sqlite:///{tmp_path / 'fleet.db'}") as (a, b):
        a.get_or_create("ann", NOW)
        a.update("ann", NOW, hobby="chess")
        interleaved: list[str] = []

        def b_writes_first(*_: Any) -> None:
            if not interleaved:
                interleaved.append("b")
                b.update("ann", NOW, name="Ann", hobby="music")
                b.record_interaction("ann", "voice", False, NOW)

        a.after_field_read = b_writes_first
        try:
            profile = a.update("ann", NOW, favorite_room="garden", pet="cat")
        finally:
            a.after_field_read = None
        assert interleaved == ["b"] and a.retries == 1
        assert (profile.name, profile.favorite_room, profile.voice_failures) == (
            "Ann",
            "garden",
            1,
        )
        assert profile.attributes == {"hobby": "music", "pet": "cat"}
        assert b.get("ann") == profile


def test_on_postgres_a_field_write_holds_the_row_and_the_other_robot_waits(pg_url: str) -> None:
    """PostgreSQL: robot A's field write locks Ann's row from its read to its commit;
    robot B's write, started in between, waits and lands on A's row (no retry)."""
    with two_robots(pg_url) as (a, b):
        a.get_or_create("ann", NOW)
        a.update("ann", NOW, hobby="chess")
        results: list[Profile] = []
        threads: list[threading.Thread] = []

        def b_writes_meanwhile(*_: Any) -> None:
            if not threads:
                thread = threading.Thread(
                    target=lambda: results.append(b.update("ann", NOW, name="Ann", hobby="music"))
                )
                threads.append(thread)
                thread.start()

        a.after_field_read = b_writes_meanwhile
        try:
            profile = a.update("ann", NOW, favorite_room="garden", pet="cat")
        finally:
            a.after_field_read = None
        threads[0].join(30)
        (after,) = results
        assert a.retries == b.retries == 0
        assert (profile.name, profile.attributes) == (None, {"hobby": "chess", "pet": "cat"})
        assert (after.name, after.favorite_room) == ("Ann", "garden")
        assert after.attributes == {"hobby": "music", "pet": "cat"}
        assert after.version == profile.version + 1
