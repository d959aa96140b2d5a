"""A fleet on one PostgreSQL: 20 robot stacks, 2,000 users walking between them; prints
one JSON object.

Each robot stack is what a daemon holds of the storage: a :class:`memory.ProfileStore`
and an :class:`agenda.Agenda` of its own (own engines and connections, its robot id as
the agenda's claimer), driven by a thread of its own on a virtual clock. Time is cut in
slots of ``--visit-s``: in each slot every robot meets one user (loads her profile, sees
her agenda, starts a session, runs an activity, asks for feedback, counts prompts and
chances, ends the session; every tenth visit writes a field too) and asks its agenda
what is due every ``--tick-s``, delivering what it gets. In ``--shared`` of the slots two
neighbouring robots see the same user in the same second, so both claim her reminders.
Every user has a reminder every ``--every-s`` (grace ``--grace-s``). The robots run as
fast as the database lets them: their virtual clocks are free to drift apart.

- ``profile_load_ms``: p50/p95/p99/max of :meth:`ProfileStore.get_or_create` (target:
  p99 ≤ 20 ms);
- ``writes_per_s``: profile writes per wall second, all robots together, sustained over
  the run (each write a transaction with its write id, as the daemon makes them);
- ``agenda``: deliveries, claims lost to another robot, duplicate deliveries (must be 0:
  each (item, fire time) delivered by one robot), and whether the log agrees;
- ``per_robot``: what one robot asked of the database per hour of its (virtual) time,
  the rates docs/fleet.md scales to 1,000 robots;
- ``connections``: the server's connections to the database while the stacks are open.

Needs a PostgreSQL server: ``--db URL`` or ``DMS_TEST_POSTGRES_URL`` (a fresh schema is
made and dropped); without one it prints ``{"skipped": reason}``.

Run: ``.venv/bin/python bench/bench_fleet.py [--robots 20] [--users 2000] [--hours 4]``
(``--quick``: 3 robots, 100 users, a quarter of an hour as fast as the database allows).
"""

from __future__ import annotations

import argparse
import json
import os
import random
import statistics
import sys
import threading
import time
import uuid
from collections import Counter
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from sqlalchemy import create_engine, text  # noqa: E402
from sqlalchemy.exc import OperationalError  # noqa: E402

from agenda import Agenda, ItemSpec, Outcome  # noqa: E402
from memory import ProfileStore  # noqa: E402
from tests.postgres import schema_url  # noqa: E402

START = datetime(2026, 11, 24, 8, 0, tzinfo=UTC)
ACTIVITIES = ("quiz", "jokes", "music", "dance", "news")


@dataclass
class Robot:
    """One robot's stack, its plan and what it measured."""

    name: str
    store: ProfileStore
    agenda: Agenda
    plan: list[str]
    """The user it meets in each slot."""
    meets: dict[int, threading.Barrier] = field(default_factory=dict)
    """Slots it shares with its neighbour: both start the visit at once."""
    load_ms: list[float] = field(default_factory=list)
    writes: int = 0
    write_s: float = 0.0
    due_calls: int = 0
    delivered: list[tuple[int, datetime]] = field(default_factory=list)
    error: BaseException | None = None
    behind_s: float = 0.0


@contextmanager
def fresh_schema(base: str) -> Iterator[str]:
    schema = f"bench_fleet_{uuid.uuid4().hex[:8]}"
    admin = create_engine(base)
    with admin.begin() as connection:
        connection.execute(text(f'CREATE SCHEMA "{schema}"'))
    try:
        yield schema_url(base, schema)
    finally:
        with admin.begin() as connection:
            connection.execute(text(f'DROP SCHEMA "{schema}" CASCADE'))
        admin.dispose()


def plans(
    robots: int, users: list[str], slots: int, shared: float, seed: int
) -> tuple[list[list[str]], list[dict[int, threading.Barrier]]]:
    """Who each robot meets in each slot: distinct users, except that with probability
    ``shared`` a robot's neighbour sees the same user in that slot (and the two start
    that visit together, so that their claims race)."""
    rng = random.Random(seed)
    out: list[list[str]] = [[] for _ in range(robots)]
    meets: list[dict[int, threading.Barrier]] = [{} for _ in range(robots)]
    for slot in range(slots):
        chosen = rng.sample(users, robots)
        for index in range(0, robots - 1, 2):
            if rng.random() < shared:
                chosen[index + 1] = chosen[index]
                meets[index][slot] = meets[index + 1][slot] = threading.Barrier(2)
        for index in range(robots):
            out[index].append(chosen[index])
    return out, meets


class Pace:
    """Virtual time against the wall clock: ``speedup`` virtual seconds per second (0: as
    fast as the database and this process allow). ``phase``: wall seconds by which this
    robot's schedule is shifted (robots in real rooms do not all start at once)."""

    def __init__(self, speedup: float, phase: float = 0.0) -> None:
        self.speedup = speedup
        self.started = time.perf_counter() + phase
        self.behind_s = 0.0
        """How far behind its schedule a robot fell at worst (wall seconds)."""

    def until(self, when: datetime) -> None:
        if not self.speedup:
            return
        due = self.started + (when - START).total_seconds() / self.speedup
        late = time.perf_counter() - due
        if late < 0:
            time.sleep(-late)
        else:
            self.behind_s = max(self.behind_s, late)


def visit(
    robot: Robot, user: str, start: datetime, visit_s: int, tick_s: int, n: int, pace: Pace
) -> None:
    store, agenda = robot.store, robot.agenda
    pace.until(start)
    began = time.perf_counter()
    store.get_or_create(user, start)
    robot.load_ms.append((time.perf_counter() - began) * 1000)
    agenda.user_perceived(user, start)

    def write(method: str, *args: Any, **kwargs: Any) -> Any:
        began = time.perf_counter()
        result = getattr(store, method)(*args, **kwargs)
        robot.write_s += time.perf_counter() - began
        robot.writes += 1
        return result

    session = write("start_session", user, start, write_id=f"session-{uuid.uuid4().hex}")
    activity = ACTIVITIES[n % len(ACTIVITIES)]
    ticks = max(1, visit_s // tick_s)
    for tick in range(ticks):
        now = start + timedelta(seconds=tick * tick_s)
        pace.until(now)
        robot.due_calls += 1
        for item in agenda.due(now, user):
            agenda.delivered(item, now)
            robot.delivered.append((item.item_id, item.fire_time))
        if tick == 1:
            write("record_interaction", user, "voice", n % 3 != 0, now, write_id=uuid.uuid4().hex)
        if tick == 2:
            write("record_initiative", user, n % 2 == 0, now, write_id=uuid.uuid4().hex)
    end = start + timedelta(seconds=visit_s - 1)
    cancelled = n % 4 == 0
    outcome = "cancelled" if cancelled else "completed"
    write(
        "record_activity",
        user,
        activity,
        start,
        end,
        outcome,
        "robot",
        cancelled,
        session,
        write_id=uuid.uuid4().hex,
    )
    write("record_feedback", user, activity, (n % 5) / 4, end, write_id=uuid.uuid4().hex)
    write("record_interaction", user, "voice", True, end, write_id=uuid.uuid4().hex)
    if n % 10 == 0:
        write("update", user, end, write_id=uuid.uuid4().hex, favorite_room=robot.name)
    write("end_session", session, end)


def drive(
    robot: Robot,
    visit_s: int,
    tick_s: int,
    speedup: float,
    phase: float,
    ready: threading.Barrier,
) -> None:
    try:
        ready.wait()
        pace = Pace(speedup, phase)
        for slot, user in enumerate(robot.plan):
            meet = robot.meets.get(slot)
            if meet is not None:
                meet.wait(120)
            start = START + timedelta(seconds=slot * visit_s)
            visit(robot, user, start, visit_s, tick_s, slot, pace)
        robot.agenda.due(START + timedelta(seconds=len(robot.plan) * visit_s), None)
        robot.behind_s = pace.behind_s
    except BaseException as error:
        robot.error = error


def percentiles(values: list[float]) -> dict[str, float]:
    ordered = sorted(values)

    def at(q: float) -> float:
        return round(ordered[min(len(ordered) - 1, int(q * len(ordered)))], 2)

    return {
        "n": len(ordered),
        "p50": at(0.50),
        "p95": at(0.95),
        "p99": at(0.99),
        "max": round(ordered[-1], 2),
        "mean": round(statistics.fmean(ordered), 2),
    }


def run(url: str, args: argparse.Namespace) -> dict[str, Any]:
    users = [f"resident{index:04d}" for index in range(args.users)]
    slots = int(args.hours * 3600 // args.visit_s)
    setup = time.perf_counter()
    seeder = ProfileStore(url)
    for user in users:
        seeder.get_or_create(user, START)
    cli = Agenda.open(url, poll_s=None)  # the command line adds everyone's reminder
    for index, user in enumerate(users):
        offset = (index * 7) % args.every_s
        cli.add(
            ItemSpec(
                user_id=user,
                kind="reminder",
                text="Time for a glass of water",
                every=args.every_s,
                grace_s=args.grace_s,
            ),
            START - timedelta(seconds=offset),
        )
    cli.close()
    setup_s = time.perf_counter() - setup
    fleet = [
        Robot(
            name=f"robot{index:02d}",
            store=ProfileStore(url),
            agenda=Agenda.open(url, claimer=f"robot{index:02d}", poll_s=args.poll_s),
            plan=plan,
            meets=meets,
        )
        for index, (plan, meets) in enumerate(
            zip(*plans(args.robots, users, slots, args.shared, args.seed), strict=True)
        )
    ]
    ready = threading.Barrier(len(fleet) + 1)

    def phase(index: int) -> float:
        """Pairs of neighbours share a phase (they may meet one user); pairs are spread
        over a tick."""
        pairs = (args.robots + 1) // 2
        return (index // 2) * args.tick_s / pairs / args.speedup if args.speedup else 0.0

    threads = [
        threading.Thread(
            target=drive,
            args=(robot, args.visit_s, args.tick_s, args.speedup, phase(index), ready),
        )
        for index, robot in enumerate(fleet)
    ]
    for thread in threads:
        thread.start()
    ready.wait()
    began = time.perf_counter()
    connections = 0
    with seeder.engine.connect() as connection:
        while any(thread.is_alive() for thread in threads):
            connections = max(
                connections,
                int(
                    connection.execute(
                        text(
                            "SELECT count(*) FROM pg_stat_activity "
                            "WHERE datname = current_database()"
                        )
                    ).scalar_one()
                ),
            )
            for thread in threads:
                thread.join(0.5)
    wall_s = time.perf_counter() - began
    errors = [f"{robot.name}: {robot.error!r}" for robot in fleet if robot.error]
    delivered = [entry for robot in fleet for entry in robot.delivered]
    duplicates = sum(count - 1 for count in Counter(delivered).values() if count > 1)
    for robot in fleet:
        robot.agenda.close()
    log = Agenda.open(url, poll_s=None)
    logged = [(o.item_id, o.fire_time) for o in log.history(None, Outcome.DELIVERED)]
    log.close()
    writes = sum(robot.writes for robot in fleet)
    visits = sum(len(robot.plan) for robot in fleet)
    retries = sum(robot.store.retries for robot in fleet)
    robot_hours = args.robots * slots * args.visit_s / 3600
    for robot in fleet:
        robot.store.close()
    seeder.close()
    loads = [ms for robot in fleet for ms in robot.load_ms]
    return {
        "robots": args.robots,
        "users": args.users,
        "virtual_hours": args.hours,
        "visits": visits,
        "shared_slots": args.shared,
        "setup_s": round(setup_s, 1),
        "wall_s": round(wall_s, 1),
        "profile_load_ms": percentiles(loads),
        "profile_load_p99_ok": percentiles(loads)["p99"] <= 20.0,
        "speedup": args.speedup,
        "switch_interval_s": args.switch_interval_s,
        "writes": writes,
        "writes_per_s": round(writes / wall_s, 1),
        "offered_writes_per_s": round(writes / robot_hours * args.robots * args.speedup / 3600, 1)
        if args.speedup
        else None,
        "worst_lag_s": round(max(robot.behind_s for robot in fleet), 2),
        "write_ms_mean": round(1000 * sum(robot.write_s for robot in fleet) / max(1, writes), 2),
        "field_write_retries": retries,
        "agenda": {
            "delivered": len(delivered),
            "claims_lost": sum(robot.agenda.claims_lost for robot in fleet),
            "duplicate_deliveries": duplicates,
            "log_matches": sorted(logged) == sorted(set(delivered)),
        },
        "per_robot": {
            "visits_per_h": round(visits / robot_hours, 1),
            "profile_writes_per_h": round(writes / robot_hours, 1),
            "profile_loads_per_h": round(len(loads) / robot_hours, 1),
            "agenda_due_calls_per_h": round(
                sum(robot.due_calls for robot in fleet) / robot_hours, 1
            ),
            "deliveries_per_h": round(len(delivered) / robot_hours, 2),
        },
        "connections": {"peak_on_server": connections, "stacks": args.robots},
        "errors": errors,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--db", default=os.environ.get("DMS_TEST_POSTGRES_URL"))
    parser.add_argument("--robots", type=int, default=20)
    parser.add_argument("--users", type=int, default=2000)
    parser.add_argument("--hours", type=float, default=2.0, help="virtual hours per robot")
    parser.add_argument(
        "--speedup",
        type=float,
        default=30.0,
        help="virtual seconds per wall second (0: as fast as the database allows)",
    )
    parser.add_argument("--visit-s", type=int, default=60)
    parser.add_argument("--tick-s", type=int, default=10)
    parser.add_argument("--every-s", type=int, default=1800)
    parser.add_argument("--grace-s", type=int, default=900)
    parser.add_argument("--poll-s", type=float, default=10.0)
    parser.add_argument("--shared", type=float, default=0.2)
    parser.add_argument("--seed", type=int, default=15)
    parser.add_argument(
        "--switch-interval-s",
        type=float,
        default=0.0005,
        help="the interpreter's thread switch interval: 20 robots share one GIL here, "
        "and Python's default (5 ms) adds up to that much to every database round trip "
        "of a thread that waits for it; a robot alone in its process does not wait",
    )
    parser.add_argument(
        "--quick", action="store_true", help="3 robots, 100 users, 15 minutes, unpaced (smoke)"
    )
    args = parser.parse_args()
    if args.quick:
        args.robots, args.users, args.hours, args.speedup = 3, 100, 0.25, 0.0
    sys.setswitchinterval(args.switch_interval_s)
    if not args.db or not args.db.startswith("postgresql"):
        print(
            json.dumps(
                {
                    "skipped": "no PostgreSQL URL: pass --db postgresql+psycopg://... or set "
                    "DMS_TEST_POSTGRES_URL"
                }
            )
        )
        return
    try:
        with create_engine(args.db).connect() as connection:
            connection.execute(text("SELECT 1"))
    except OperationalError as error:  # the server is down or refuses us: say so
        reason = str(error.orig or error).strip().splitlines()[0]
        print(json.dumps({"skipped": f"PostgreSQL at {args.db.split('@')[-1]}: {reason}"}))
        return
    with fresh_schema(args.db) as url:
        result = run(url, args)
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
