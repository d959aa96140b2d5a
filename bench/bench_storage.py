"""Storage under faults; prints one JSON object.

- ``lock_gap_s``: the longest gap between ``dms/state`` messages of a real daemon process
  while another process holds SQLite's write lock for 20 s and a user's activities are
  started and cancelled (each cancel is a profile write). Target ≤ 0.6 s.
- ``spool_writes_per_s``: writes per second taken by the profile service (writer thread,
  fsync'd spool) while the database is locked.
- ``drain_s``: time for the spooled writes (10,000) to reach the database once it is back.

Run: ``.venv/bin/python bench/bench_storage.py [--hold-s 20] [--quick]``.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from datetime import UTC, datetime, timedelta
from itertools import pairwise
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from dms.profiles import ProfileService  # noqa: E402
from memory import ProfileStore  # noqa: E402
from tests.integration.harness import Collector, put, running_daemon  # noqa: E402
from tests.integration.test_storage import (  # noqa: E402
    LockHolder,
    _ts,
    begin_session,
    jokes_round,
    pace,
)

WRITES = 10_000


def lock_gap(hold_s: float) -> tuple[float, int]:
    """Longest dms/state gap (s) while the lock is held, and the writes made meanwhile."""
    with tempfile.TemporaryDirectory(prefix="dms-bench-") as folder:
        tmp = Path(folder)
        with running_daemon(tmp) as (daemon, session):
            decisions = Collector(session, "robots/mini/dms/decision")
            states = begin_session(session)
            jokes_round(session, decisions)
            holder = LockHolder(tmp / "dms.db")
            start = states.mark()
            first = states.wait_for(lambda s: True, start=start)
            rounds = 0
            while _ts(states.messages[-1]) - _ts(first) < hold_s:
                jokes_round(session, decisions)
                rounds += 1
                pace(states)
            end = states.mark()
            holder.release()
            put(session, "perception/user", {"present": False})
            daemon.terminate()
        times = [_ts(s) for s in states.messages[start:end]]
        return max(b - a for a, b in pairwise(times)), rounds


def spool_and_drain(writes: int = WRITES) -> tuple[float, float]:
    """Writes/s into the spool while the database is locked; seconds to drain them."""
    with tempfile.TemporaryDirectory(prefix="dms-bench-") as folder:
        db = Path(folder) / "dms.db"
        store = ProfileStore(f"sqlite:///{db}", busy_timeout_s=0.2)
        service = ProfileService(store, lambda key, line: None)
        now = datetime(2026, 11, 23, 10, 0, tzinfo=UTC)
        service.load("ann", now, wait_s=10.0)
        holder = LockHolder(db)
        service.record_feedback("ann", "quiz", 0.5, now)
        deadline = time.monotonic() + 10
        while not len(service.writer.spool) and time.monotonic() < deadline:
            time.sleep(0.01)  # the first write finds the lock and starts the spool
        started = time.perf_counter()
        for n in range(1, writes):
            service.record_feedback("ann", "quiz", (n % 5) / 4, now + timedelta(seconds=n))
        rate = (writes - 1) / (time.perf_counter() - started)
        assert service.pending_writes == writes
        holder.release()
        started = time.perf_counter()
        assert service.writer.wait_idle(600)
        drain = time.perf_counter() - started
        assert store.export("ann")["profile"]["scores"]["quiz"]["feedback_count"] == writes
        service.close()
        store.close()
        return rate, drain


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--hold-s", type=float, default=20.0)
    parser.add_argument(
        "--quick", action="store_true", help="the lock held 3 s, 500 writes (smoke)"
    )
    args = parser.parse_args()
    hold_s, writes = (3.0, 500) if args.quick else (args.hold_s, WRITES)
    gap, rounds = lock_gap(hold_s)
    rate, drain = spool_and_drain(writes)
    print(
        json.dumps(
            {
                "lock_held_s": hold_s,
                "lock_gap_s": round(gap, 3),
                "lock_gap_target_s": 0.6,
                "writes_under_lock": rounds,
                "spool_writes_per_s": round(rate),
                "writes": writes,
                "drain_s": round(drain, 2),
            }
        )
    )


if __name__ == "__main__":
    main()
