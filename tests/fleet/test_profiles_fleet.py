"""Robots sharing one profile store: concurrent writes of one person, replays of a spool.

The failure these tests guard against: two daemons serving the same person wrote 20 runs and 18 were
stored (``record_activity refused: duplicate key value violates unique constraint
"activity_scores_pkey"``: both created the score row).
"""

from __future__ import annotations

import threading
from datetime import timedelta
from pathlib import Path

from dms.profiles import ProfileService
from dms.storage import Waiter, Write
from memory import ProfileStore
from memory.spool import write_spool
from tests.fleet.conftest import NOW

RUNS = 20


def _in_parallel(*jobs: object) -> None:
    """Run the callables on threads of their own, released at once; re-raise a failure."""
    start = threading.Barrier(len(jobs))
    errors: list[BaseException] = []

    def run(job: object) -> None:
        try:
            start.wait()
            job()  # type: ignore[operator]
        except BaseException as error:
            errors.append(error)

    threads = [threading.Thread(target=run, args=(job,)) for job in jobs]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(120)
    assert not any(thread.is_alive() for thread in threads), "a robot is stuck"
    assert not errors, errors


def test_two_stores_record_20_activities_each_for_a_new_person_and_keep_40(pg_url: str) -> None:
    robots = [ProfileStore(pg_url), ProfileStore(pg_url)]
    try:

        def robot(store: ProfileStore, index: int) -> None:
            store.get_or_create("ann", NOW)  # a new person: both create her at once
            for run in range(RUNS):
                started = NOW + timedelta(minutes=run)
                store.record_activity(
                    "ann",
                    "quiz",
                    started,
                    started + timedelta(seconds=30),
                    "completed",
                    f"robot{index}",
                    False,
                )
                store.record_feedback("ann", "quiz", 1.0, started)

        _in_parallel(*(lambda s=store, i=i: robot(s, i) for i, store in enumerate(robots)))
        profile = robots[1].get("ann")
        assert profile.scores["quiz"].completions == 2 * RUNS
        assert profile.scores["quiz"].feedback_count == 2 * RUNS
        assert profile.scores["quiz"].feedback_sum == 2 * RUNS
        history = robots[0].export("ann")
        assert len(history["activities"]) == 2 * RUNS
        assert len(history["feedback"]) == 2 * RUNS
    finally:
        for store in robots:
            store.close()


def test_two_daemons_profile_services_lose_nothing_and_quarantine_nothing(
    fleet_url: str, tmp_path: Path
) -> None:
    """The daemon's own path: writes queued from the tick, applied by each writer thread."""
    reports: list[tuple[str, str]] = []
    services = [
        ProfileService(
            ProfileStore(fleet_url),
            lambda part, message: reports.append((part, message)),
            spool_path=tmp_path / f"robot{index}.spool",
            quarantine_path=tmp_path / f"robot{index}.quarantine",
        )
        for index in range(2)
    ]
    try:

        def robot(service: ProfileService) -> None:
            service.load("ann", NOW, wait_s=10)
            session = service.start_session("ann", NOW)
            for run in range(RUNS):
                started = NOW + timedelta(minutes=run)
                ended = started + timedelta(seconds=30)
                service.record_activity("ann", "quiz", started, ended, "completed", "robot", False)
                service.record_activity("ann", "jokes", started, ended, "x", "user", True)
                service.record_interaction("ann", "voice", False, ended)
                service.record_initiative("ann", run % 2 == 0, ended)
            service.end_session(session, NOW + timedelta(hours=1))

        _in_parallel(*(lambda s=service: robot(s) for service in services))
        for service in services:
            assert service.writer.wait_idle(60)
        profile = services[0].store.get("ann")
        assert (profile.scores["quiz"].completions, profile.scores["jokes"].cancellations) == (
            2 * RUNS,
            2 * RUNS,
        )
        assert profile.initiative_offered <= 2 * RUNS  # halved past 40 chances: none lost
        assert len(services[1].store.export("ann")["activities"]) == 4 * RUNS
        assert len(services[1].store.export("ann")["sessions"]) == 2
        assert reports == []
        assert all(not service.writer.quarantine.path.exists() for service in services)
    finally:
        for service in services:
            service.close()
            service.store.close()


def test_a_spool_replayed_after_a_crash_applies_each_write_once(
    fleet_url: str, tmp_path: Path
) -> None:
    """The database took the writes but the crash came before the spool marked them done:
    the next start replays them; their ids are in the database, so they count once, and
    the session they started is the same one."""
    store = ProfileStore(fleet_url)
    spool_path, quarantine = tmp_path / "dms.spool", tmp_path / "dms.quarantine"
    first = ProfileService(
        store, lambda *_: None, threaded=False, spool_path=spool_path, quarantine_path=quarantine
    )
    sent: list[Write] = []
    submit = first.writer.submit

    def recording(write: Write, waiter: Waiter | None = None) -> None:
        sent.append(write)
        submit(write, waiter)

    first.writer.submit = recording  # type: ignore[method-assign]
    first.load("ann", NOW)
    key = first.start_session("ann", NOW)
    first.record_feedback("ann", "quiz", 0.5, NOW)
    first.record_activity("ann", "quiz", NOW, NOW, "completed", "robot", False, key)
    first.record_initiative("ann", True, NOW)
    first.update("ann", NOW, name="Ann")
    session_id = first.writer.binds[key]
    applied = store.export("ann")
    assert all("write_id" in w.kwargs or "key" in w.kwargs for w in sent[1:])
    # kill -9 before the spool said done: the next start finds every write in it.
    write_spool(spool_path, [write.to_json() for write in sent], {})
    again = ProfileService(
        store, lambda *_: None, threaded=False, spool_path=spool_path, quarantine_path=quarantine
    )
    again.retry(NOW + timedelta(minutes=1))
    assert again.writer.replayed == len(sent) and again.pending_writes == 0
    assert again.writer.binds[key] == session_id
    replayed = store.export("ann")
    assert replayed["profile"] == applied["profile"]
    assert (len(replayed["sessions"]), len(replayed["feedback"]), len(replayed["activities"])) == (
        1,
        1,
        1,
    )
    assert not quarantine.exists()
    first.close()
    again.close()
    store.close()
