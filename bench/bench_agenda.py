"""Benchmark: the agenda's due-item lookup on every tick (2 Hz).

10,000 items across 1,000 users (daily, weekday and weekly cron items in Madrid time,
4 h and 6 h intervals, one-off reminders), 48 hours of virtual time, one visitor at a
time (a different user every 20 minutes) who receives what is due for them; the other
users' items wait their grace time and are recorded as missed. Only ``Agenda.due`` is
timed, on an agenda built as the daemon builds it: its polls of the database, its
claims and its records run on its own threads, and the work a call starts there is let
finish before the next call (untimed), as the half second between two ticks does.
Also: the time to add the items, to reopen the agenda (a daemon restart) and to
recover. Prints one JSON object. Target: p99 <= 0.5 ms.

    .venv/bin/python bench/bench_agenda.py [--users N] [--hours H] [--quick]
"""

from __future__ import annotations

import argparse
import json
import random
import statistics
import tempfile
import time
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

from agenda import Agenda, ItemSpec

START = datetime(2026, 11, 23, 6, 0, tzinfo=UTC)
TICK = timedelta(seconds=0.5)


def specs(user: str, rng: random.Random) -> list[ItemSpec]:
    """Ten items of one user."""
    minute = rng.randrange(60)
    base: dict[str, Any] = {"user_id": user, "tz": "Europe/Madrid"}
    items = [
        ItemSpec(kind="reminder", text="Pills", cron=f"{minute} 9 * * *", lead_s=300, **base),
        ItemSpec(
            kind="event",
            activity="cognitive_stimulation",
            cron="0 10 * * MON",
            priority="high",
            **base,
        ),
        ItemSpec(kind="reminder", text="Walk", cron=f"{minute} 17 * * 1-5", **base),
        ItemSpec(kind="reminder", text="Water", every=4 * 3600, **base),
        ItemSpec(kind="event", activity="talk", every=6 * 3600, grace_s=1800, **base),
    ]
    for _ in range(5):
        at = START + timedelta(seconds=rng.uniform(60, 48 * 3600))
        items.append(ItemSpec(kind="reminder", text="Call", at=at, grace_s=900, **base))
    return items


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))]


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--users", type=int, default=1000)
    parser.add_argument("--hours", type=float, default=48.0)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--quick", action="store_true", help="50 users, 2 hours (smoke)")
    args = parser.parse_args()
    if args.quick:
        args.users, args.hours = 50, 2.0
    rng = random.Random(args.seed)
    users = [f"user{i:04d}" for i in range(args.users)]
    with tempfile.TemporaryDirectory() as folder:
        url = f"sqlite:///{Path(folder) / 'dms.db'}"
        agenda = Agenda.open(url)
        t0 = time.perf_counter()
        count = 0
        for user in users:
            for spec in specs(user, rng):
                # Items were added at different times before the run (spread interval anchors).
                agenda.add(spec, START - timedelta(seconds=rng.uniform(0, 4 * 3600)))
                count += 1
        add_s = time.perf_counter() - t0
        agenda.close()

        t0 = time.perf_counter()
        agenda = Agenda.open(url, background=True)
        reopen_s = time.perf_counter() - t0
        t0 = time.perf_counter()
        agenda.recover(START)
        recover_s = time.perf_counter() - t0

        ticks = int(args.hours * 3600 / TICK.total_seconds())
        visit_ticks = 20 * 60 * 2
        timings: list[float] = []
        delivered = 0
        now = START
        present = users[0]
        for tick in range(ticks):
            now += TICK
            if tick % visit_ticks == 0:
                present = rng.choice(users)
            agenda.wait_idle(5.0)
            t = time.perf_counter_ns()
            due = agenda.due(now, present)
            timings.append((time.perf_counter_ns() - t) / 1e6)
            for item in due:
                agenda.delivered(item, now)
                delivered += 1
        missed_runs = agenda.missed_log(None)
        agenda.close()
    print(
        json.dumps(
            {
                "items": count,
                "users": args.users,
                "virtual_hours": args.hours,
                "ticks": ticks,
                "due_p50_ms": round(percentile(timings, 0.50), 4),
                "due_p99_ms": round(percentile(timings, 0.99), 4),
                "due_p999_ms": round(percentile(timings, 0.999), 4),
                "due_max_ms": round(max(timings), 3),
                "due_mean_ms": round(statistics.fmean(timings), 4),
                "p99_target_ms": 0.5,
                "p99_ok": percentile(timings, 0.99) <= 0.5,
                "delivered": delivered,
                "missed_occurrences": sum(m.count for m in missed_runs),
                "add_ms_per_item": round(add_s / count * 1e3, 3),
                "reopen_s": round(reopen_s, 3),
                "recover_s": round(recover_s, 3),
            }
        )
    )


if __name__ == "__main__":
    main()
