"""One daemon through a simulated month under a schedule of faults; one JSON object.

The daemon is built and driven as in ``bench_week.py`` (settings from
:func:`dms.config.load_config`, the real Zenoh bus on a free loopback port, the simulated
Mini, a :class:`~dms.kernel.clock.VirtualClock`, the daemon's own one-tick method every
0.5 virtual seconds, three users on their personas' schedules). On top of that, every
simulated day, while the users visit (10:30, 11:00, 16:30) or at night:

- disk full: the database is on a small tmpfs, filled to the last byte from 10:00 to
  12:00 (the writes wait in the spare spool folder, on another filesystem, as in a
  deployment with ``[storage] spool_dir``); without ``mount`` (not root) it is skipped,
  and the JSON says why;
- SQLite locked: another process holds the database's write lock from 16:15 to 17:15;
- robot silent: the robot acknowledges no command for ten minutes (16:35);
- perception restarts: the perception module's token goes away for two minutes (10:40);
- floods (16:40): 5,000 touches and 500 ``reload_rules`` requests at one instant, 100
  made-up ``params/env`` messages, and a peer (on 127.0.0.1) declaring 1,000 junk tokens;
- rules reloads: three a day;
- clock steps: the wall clock is set an hour back and, a while later, an hour forward,
  at 03:00 (half an hour) and during a visit (16:50, five minutes), while the monotonic
  clock goes on.

Reported: profile writes acknowledged (queued with an id) and stored (their ids in
``applied_writes`` once every fault is over), the agenda's records the same way, resident
memory by day, the longest gap between two ``dms/state`` messages (virtual seconds) and
when it was, the faults applied, and for the clock steps the ticks run while the clock
stood stepped. Not a timed test: a simulated day takes 45-85 s on two cores, a month
about 23 minutes (``--days`` runs fewer).

Usage: ``.venv/bin/python bench/bench_soak.py [--days 30] [--quick]``
(``--quick``: four simulated hours, a visit every 25 minutes, every fault once).
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import json
import logging
import random
import sqlite3
import subprocess
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import zenoh  # noqa: E402
from bench_week import DAY_S, Room, TappedBus, free_port, settle, status_mb  # noqa: E402

from dms.bus import make_config  # noqa: E402
from dms.config import load_config  # noqa: E402
from dms.daemon import Daemon  # noqa: E402
from dms.kernel import keys  # noqa: E402
from dms.kernel.clock import VirtualClock  # noqa: E402
from dms.storage import STORE_OPS  # noqa: E402
from sim.adapters import daily_reminder, ensure_user  # noqa: E402
from sim.longterm import START, PlannedVisit, plan_visits  # noqa: E402
from sim.persona import load_persona, shipped_personas  # noqa: E402
from sim.robot import SimRobot  # noqa: E402
from sim.user import SimulatedUser  # noqa: E402

HOUR_S = 3600.0
DISK_MB = 64
"""The tmpfs the database lives on (filled to the last byte while the disk is full)."""
WAIT_S = 120.0
"""How long the end of the run waits for every write to land."""
IDENTIFIED = STORE_OPS - {"get_or_create", "find", "last_run", "end_session"}
"""Profile writes that carry an id, recorded in ``applied_writes`` when stored (the
reads carry none, and a session's end is its start's key)."""

HOLD = """
import sqlite3, sys
connection = sqlite3.connect(sys.argv[1], isolation_level=None, timeout=30)
connection.execute("BEGIN EXCLUSIVE")
print("locked", flush=True)
sys.stdin.readline()
connection.execute("ROLLBACK")
"""


@dataclass(frozen=True, slots=True)
class Fault:
    """One fault: ``kind`` from ``start_s`` to ``end_s`` (virtual monotonic seconds)."""

    start_s: float
    end_s: float
    kind: str


def plan_faults(days: float, quick: bool) -> list[Fault]:
    """Every fault once a day at its hour (``quick``: once, ten minutes apart)."""
    if quick:
        order = ["disk_full", "sqlite_locked", "robot_silent", "perception_restart"]
        order += ["flood", "rules_reload", "clock_step"]
        return [
            Fault(600.0 * (n + 1), 600.0 * (n + 1) + 300.0, kind) for n, kind in enumerate(order)
        ]
    daily = [  # (hour of day, hours, kind); visits at 10:30, 11:00 and 16:30
        (10.0, 2.0, "disk_full"),
        (10 + 40 / 60, 2 / 60, "perception_restart"),
        (10.75, 0.0, "rules_reload"),
        (11 + 10 / 60, 0.0, "rules_reload"),
        (16.25, 1.0, "sqlite_locked"),
        (16 + 35 / 60, 0.0, "rules_reload"),
        (16 + 35 / 60, 10 / 60, "robot_silent"),
        (16 + 40 / 60, 0.0, "flood"),
        (16 + 50 / 60, 5 / 60, "clock_step"),
        (3.0, 0.5, "clock_step"),
    ]
    faults = []
    for day in range(int(days + 0.999)):
        for hour, hours, kind in daily:
            start = day * DAY_S + hour * HOUR_S
            faults.append(Fault(start, start + hours * HOUR_S, kind))
    return sorted(
        (fault for fault in faults if fault.end_s < days * DAY_S), key=lambda f: f.start_s
    )


class Disk:
    """A small tmpfs for the database, or the temporary folder when none can be mounted."""

    def __init__(self, tmp: Path) -> None:
        self.folder = tmp / "disk"
        self.folder.mkdir()
        try:
            mounted = subprocess.run(
                ["mount", "-t", "tmpfs", "-o", f"size={DISK_MB}m", "tmpfs", str(self.folder)],
                capture_output=True,
                text=True,
            )
        except OSError as error:  # no mount(8) here
            self.mounted, self.why_not = False, str(error)
        else:
            self.mounted = mounted.returncode == 0
            self.why_not = "" if self.mounted else " ".join(mounted.stderr.split()) or "failed"
        self.filler = self.folder / "filler"

    def fill(self) -> None:
        with self.filler.open("wb", buffering=0) as out:
            for size in (1 << 20, 1 << 16, 1 << 12, 1 << 9, 1):
                try:
                    while True:
                        out.write(b"\0" * size)
                except OSError as error:
                    if error.errno != errno.ENOSPC:
                        raise

    def empty(self) -> None:
        self.filler.unlink(missing_ok=True)

    def unmount(self) -> None:
        if self.mounted:
            subprocess.run(["umount", "-l", str(self.folder)], check=False)


class LockHolder:
    """Another process holding SQLite's write lock until :meth:`release`."""

    def __init__(self, db: Path) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, "-c", HOLD, str(db)],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
        )
        assert self.proc.stdout is not None
        if self.proc.stdout.readline().strip() != "locked":
            raise RuntimeError("the lock holder could not lock the database")

    def release(self) -> None:
        assert self.proc.stdin is not None
        self.proc.stdin.write("go\n")
        self.proc.stdin.flush()
        self.proc.wait(30)


def peer_session(port: int) -> zenoh.Session:
    """A Zenoh peer on 127.0.0.1 only (no multicast), connected to the daemon."""
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("connect/endpoints", json.dumps([f"tcp/127.0.0.1:{port}"]))
    conf.insert_json5("listen/endpoints", "[]")
    conf.insert_json5("scouting/multicast/enabled", "false")
    return zenoh.open(conf)


class Counted:
    """Counts what a writer acknowledged: entries queued through ``submit``/``submit_all``."""

    def __init__(self, writer: Any, counts: Callable[[Any], bool]) -> None:
        self.acknowledged = 0
        submit, submit_all = writer.submit, writer.submit_all

        def counted_submit(entry: Any, *rest: Any) -> None:
            self.acknowledged += counts(entry)
            submit(entry, *rest)

        def counted_submit_all(entries: Any) -> None:
            self.acknowledged += sum(counts(entry) for entry in entries)
            submit_all(entries)

        writer.submit, writer.submit_all = counted_submit, counted_submit_all


def quarantined(folder: Path) -> Counter[str]:
    """Writes the database refused for good (the ``.quarantine`` files), by reason."""
    reasons: Counter[str] = Counter()
    for path in folder.glob("*.quarantine"):
        for line in path.read_text(encoding="utf-8").splitlines():
            with contextlib.suppress(ValueError, AttributeError):
                record = json.loads(line)
                reasons[f"{record.get('op', '?')}: {record.get('error', '?')}"] += 1
    return reasons


def count_rows(db: Path, table: str) -> int:
    with contextlib.closing(sqlite3.connect(db)) as connection:
        return int(connection.execute(f"SELECT count(*) FROM {table}").fetchone()[0])


class Faults:
    """Starts and ends each kind of fault on the running daemon."""

    def __init__(
        self, daemon: Daemon, robot: SimRobot, clock: VirtualClock, disk: Disk, db: Path, port: int
    ) -> None:
        self.daemon, self.robot, self.clock, self.disk, self.db = daemon, robot, clock, disk, db
        self.port = port
        self.applied: Counter[str] = Counter()
        self.skipped: dict[str, str] = {}
        self.storage_down = False
        self.perception_down = False
        self._lock: LockHolder | None = None
        self._peer: zenoh.Session | None = None
        self._tokens: list[Any] = []
        self._reloads_asked = 0

    def start(self, kind: str) -> None:
        getattr(self, f"_start_{kind}")()

    def end(self, kind: str) -> None:
        getattr(self, f"_end_{kind}", lambda: None)()

    def _start_disk_full(self) -> None:
        if not self.disk.mounted:
            self.skipped["disk_full"] = f"cannot mount a tmpfs: {self.disk.why_not}"
            return
        self.disk.fill()
        self.storage_down = True
        self.applied["disk_full"] += 1

    def _end_disk_full(self) -> None:
        self.disk.empty()
        self.storage_down = False

    def _start_sqlite_locked(self) -> None:
        self._lock = LockHolder(self.db)
        self.storage_down = True
        self.applied["sqlite_locked"] += 1

    def _end_sqlite_locked(self) -> None:
        if self._lock is not None:
            self._lock.release()
            self._lock = None
        self.storage_down = False

    def _start_robot_silent(self) -> None:
        self.robot.set_fault("*", "hang")
        self.applied["robot_silent"] += 1

    def _end_robot_silent(self) -> None:
        self.robot.set_fault("*", None)

    def _start_perception_restart(self) -> None:
        self.daemon.on_liveliness(keys.PERCEPTION_USER, False)
        self.perception_down = True
        self.applied["perception_restart"] += 1

    def _end_perception_restart(self) -> None:
        self.daemon.on_liveliness(keys.PERCEPTION_USER, True)
        self.perception_down = False

    def _start_flood(self) -> None:
        daemon = self.daemon
        for _ in range(5000):
            daemon.on_input(keys.PERCEPTION_TOUCH, b'{"part": "head", "kind": "tap"}')
        reload = b'{"action": "reload_rules", "by": "flood"}'
        for _ in range(500):
            daemon.on_input(keys.REQUEST, reload)
        for n in range(100):
            names = {f"made_up_{n}_{i}": i for i in range(50)}
            daemon.on_input(keys.PARAMS_ENV, json.dumps(names).encode())
        if self._peer is None:
            self._peer = peer_session(self.port)
        liveliness = self._peer.liveliness()
        robot = self.daemon.settings.robot_id
        self._tokens = [
            liveliness.declare_token(keys.absolute(robot, f"alive/junk/{n}")) for n in range(1000)
        ]
        self.applied["flood"] += 1

    def _end_flood(self) -> None:
        for token in self._tokens:
            token.undeclare()
        self._tokens = []

    def _start_rules_reload(self) -> None:
        self.daemon.reloader.request()
        self._reloads_asked += 1
        self.applied["rules_reload"] += 1

    def _start_clock_step(self) -> None:
        self.clock.step_wall(-HOUR_S)
        self.applied["clock_step"] += 1

    def _end_clock_step(self) -> None:
        self.clock.step_wall(HOUR_S)

    def close(self) -> None:
        self._end_flood()
        if self._peer is not None:
            self._peer.close()  # type: ignore[no-untyped-call]
        if self._lock is not None:
            self._end_sqlite_locked()
        self._end_disk_full()


def run(days: float, quick: bool, seed: int) -> dict[str, Any]:
    """Build the daemon, drive it through ``days`` of virtual time under the faults."""
    wall = time.perf_counter()
    tmp_dir = tempfile.TemporaryDirectory(prefix="dms-soak-")
    tmp = Path(tmp_dir.name)
    disk = Disk(tmp)
    db = disk.folder / "soak.db"
    spare = tmp / "spare-spool"
    spare.mkdir()
    config = tmp / "dms.toml"
    config.write_text(f'[storage]\nspool_dir = "{spare}"\n')
    port = free_port()
    settings = load_config(
        config,
        db=f"sqlite:///{db}",
        listen=[f"tcp/127.0.0.1:{port}"],
        seed=seed,
        use_environment=False,
    )
    clock = VirtualClock(START)
    room = Room(clock)
    gaps = StateGaps(clock)

    def tap(key: str, payload: Mapping[str, Any]) -> None:
        room.hear(key, payload)
        if key == keys.DMS_STATE:
            gaps.state()
        elif key == keys.DMS_ERRORS:
            gaps.error(str(payload.get("key")))

    zenoh_settings = settings.zenoh
    bus = TappedBus(
        settings.robot_id,
        make_config(zenoh_settings.listen, zenoh_settings.connect, zenoh_settings.config_file),
        tap,
    )
    robots: list[SimRobot] = []

    def make_robot(robot_seed: int) -> SimRobot:
        robots.append(SimRobot(rng_seed=robot_seed))
        return robots[-1]

    daemon = Daemon(settings, print_decisions=False, bus=bus, clock=clock, sim_robot=make_robot)
    daemon.start()
    profiles = daemon.stack.controller.deps.profiles
    agenda = daemon.stack.agenda
    assert profiles is not None and agenda is not None
    profile_writes = Counted(profiles.writer, lambda write: write.method in IDENTIFIED)
    agenda_records = Counted(agenda._writer, lambda entry: True)
    faults = Faults(daemon, robots[0], clock, disk, db, port)

    rng = random.Random(seed)
    names = [name for name in shipped_personas() if name != "demo"][:3]
    personas = [load_persona(name) for name in names]
    people = [SimulatedUser(p, random.Random(rng.random())) for p in personas]
    for person, persona in zip(people, personas, strict=True):
        ensure_user(daemon.stack, person.user_id, START)
        if persona.visits:
            first = persona.visits[0].at
            minute = first.hour * 60 + first.minute + 10
            daily_reminder(agenda, person.user_id, minute // 60 % 24, minute % 60, START)
    if quick:  # a visit every 25 minutes, through the faults
        visits = [PlannedVisit(n % 3, 300.0 + n * 1500, 1500.0 + n * 1500) for n in range(9)]
    else:
        visits = plan_visits(personas, max(1, int(days + 0.999)), rng)
    schedule = plan_faults(days, quick)
    events = sorted(
        [(f.start_s, 0, f.kind) for f in schedule] + [(f.end_s, 1, f.kind) for f in schedule]
    )

    period = settings.controller.tick_period_s
    end_s = days * DAY_S
    next_tick, next_day, next_hour = period, DAY_S, HOUR_S
    index = event = ticks = 0
    leave_at: float | None = None
    by_day: list[float] = []
    stepped_ticks: list[int] = []
    try:
        while True:
            t = clock.monotonic()
            upcoming = next_tick
            arrival = visits[index].start_s if index < len(visits) and leave_at is None else None
            if arrival is not None:
                upcoming = min(upcoming, arrival)
            if leave_at is not None:
                upcoming = min(upcoming, leave_at)
            if event < len(events):
                upcoming = min(upcoming, events[event][0])
            user = room.user
            due = user.next_due() if user is not None else None
            if due is not None:
                upcoming = min(upcoming, max(t, (due - clock.now()).total_seconds() + t))
            if upcoming > end_s:
                break
            if upcoming > t:
                clock.advance(upcoming - t)
                t = clock.monotonic()
            now = clock.now()
            while event < len(events) and events[event][0] <= t:
                _, ends, kind = events[event]
                event += 1
                if ends:
                    faults.end(kind)
                    if kind == "clock_step":
                        stepped_ticks[-1] = ticks - stepped_ticks[-1]
                else:
                    faults.start(kind)
                    if kind == "clock_step":
                        stepped_ticks.append(ticks)
            if leave_at is not None and t >= leave_at:
                assert room.user is not None
                room.user.leave(now)
                room.absent, room.user, leave_at = room.user, None, None
                if not faults.storage_down:
                    settle(daemon)
            elif arrival is not None and t >= arrival:
                visit = visits[index]
                index += 1
                room.user, leave_at = people[visit.user], visit.end_s
                room.user.arrive(now)
            urgent = False
            user = room.user
            if user is not None and (due := user.next_due()) is not None and due <= now:
                for key, message in user.due(now):
                    daemon.on_input(key, message.model_dump_json().encode())
                    urgent = urgent or key in keys.URGENT_INPUTS
            if next_tick <= t:
                if not faults.perception_down:
                    daemon.on_input(keys.PERCEPTION_USER, room.perception())
                daemon._run_tick(urgent=False)
                ticks += 1
                next_tick += period
            elif urgent:
                daemon._run_tick(urgent=True)
            if t >= next_hour:
                if not faults.storage_down:
                    settle(daemon)
                next_hour += HOUR_S
            if t >= next_day:
                by_day.append(round(status_mb("VmRSS"), 1))
                next_day += DAY_S
    finally:
        faults.close()
    landed = profiles.writer.wait_idle(WAIT_S) and agenda.wait_idle(WAIT_S)
    rss_after, peak = status_mb("VmRSS"), status_mb("VmHWM")
    pending = profiles.pending_writes
    reloads = daemon.reloader.reloads
    daemon.close()
    stored = count_rows(db, "applied_writes")
    agenda_stored = count_rows(db, "agenda_occurrences")
    refused = quarantined(disk.folder) + quarantined(spare)
    disk.unmount()
    tmp_dir.cleanup()
    skipped = {kind: why for kind, why in faults.skipped.items()}
    return {
        "benchmark": "soak",
        "days": days,
        "ticks": ticks,
        "visits": index,
        "wall_s": round(time.perf_counter() - wall, 1),
        "writes_acknowledged": profile_writes.acknowledged,
        "writes_stored": stored,
        "writes_pending_at_end": pending,
        "writes_quarantined": sum(refused.values()),
        "writes_lost": profile_writes.acknowledged - stored - sum(refused.values()) - pending,
        "quarantined_by_reason": dict(sorted(refused.items())),
        "writes_all_landed": landed,
        "agenda_records_acknowledged": agenda_records.acknowledged,
        "agenda_records_stored": agenda_stored,
        "rss_mb_by_day": by_day,
        "rss_mb_after": round(rss_after, 1),
        "rss_mb_peak": round(peak, 1),
        "longest_state_gap_s": round(gaps.longest_s, 3),
        "longest_state_gap_at_s": round(gaps.longest_at_s, 1),
        "faults_applied": dict(sorted(faults.applied.items())),
        "faults_skipped": skipped,
        "reloads": reloads,
        "clock_steps": {
            "steps": len(stepped_ticks),
            "fewest_ticks_while_stepped": min(stepped_ticks, default=0),
            "kept_ticking": bool(stepped_ticks) and min(stepped_ticks) > 0,
            "reported": gaps.errors.get("clock", 0),
        },
        "reports_by_key": dict(sorted(gaps.errors.items())),
    }


class StateGaps:
    """The longest stretch of virtual time without a ``dms/state``; reports by key."""

    def __init__(self, clock: VirtualClock) -> None:
        self.clock = clock
        self.last_s: float | None = None
        self.longest_s = 0.0
        self.longest_at_s = 0.0
        self.errors: Counter[str] = Counter()

    def state(self) -> None:
        t = self.clock.monotonic()
        if self.last_s is not None and t - self.last_s > self.longest_s:
            self.longest_s, self.longest_at_s = t - self.last_s, self.last_s
        self.last_s = t

    def error(self, key: str) -> None:
        self.errors[key] += 1


@contextlib.contextmanager
def quiet_logs() -> Iterator[None]:
    """The daemon's warnings during faults stay off stderr; the JSON counts its reports."""
    level = logging.root.level
    logging.root.setLevel(logging.ERROR)
    try:
        yield
    finally:
        logging.root.setLevel(level)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--days", type=float, default=30.0, help="virtual days (default 30)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--quick", action="store_true", help="four simulated hours (smoke)")
    args = parser.parse_args()
    with quiet_logs():
        print(json.dumps(run(4 / 24 if args.quick else args.days, args.quick, args.seed)))


if __name__ == "__main__":
    main()
