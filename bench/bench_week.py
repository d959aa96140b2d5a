"""Resident memory of one daemon after a simulated week; one JSON object.

``dms run`` has no clock faster than real time: :class:`dms.daemon.Daemon` takes a
``Clock``, but its loop waits on a :class:`~dms.kernel.clock.Ticker` against real
seconds. So this bench is the in-process variant: it builds the daemon as ``dms run``
does (settings from :func:`dms.config.load_config` with a free loopback port and a fresh
SQLite file, the real Zenoh bus, the simulated Mini), hands it a
:class:`~dms.kernel.clock.VirtualClock`, and calls the daemon's own one-tick method
(``Daemon._run_tick``, what ``Daemon.loop`` runs for each tick: the tick, then its
decisions and state published on Zenoh) every 0.5 virtual seconds, day and night, for
``--days`` (default 7: 1,209,600 ticks). The process holds nothing else for long, so
its resident size is the daemon's.

Three users (the first shipped personas, as ``dms sim longterm``) visit on their
personas' schedules (:func:`sim.longterm.plan_visits`), each with a daily reminder.
What a perception module and the person would publish goes through
``Daemon.on_input``, the Zenoh input path (rate caps, parsing, the input board): the
user's perception at 2 Hz (absent between visits), and their answers, touches and
requests when they make them, an urgent one followed by a tick at once as the loop
does. The users hear the robot's commands and see its decisions in what the daemon
publishes. Profiles, sessions and the agenda are written to the SQLite file as live; at
each departure and every simulated hour the bench waits for those background writes to
finish, as the real minutes between ticks would let them (unpaced, a loaded machine
once left a backlog that kept the process at 196 MB instead of about 118 MB).

Reported: ``VmRSS`` at ready and after each simulated day, after the week, and the
peak (``VmHWM``); target <= 150 MB after the week (and <= 120 MB idle after ten real
minutes: ``bench_start.py``). Not a timed test; it takes minutes.

Usage: ``.venv/bin/python bench/bench_week.py [--days 7] [--users 3] [--quick]``
(``--quick``: a simulated hour).
"""

from __future__ import annotations

import argparse
import json
import random
import socket
import sys
import tempfile
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from dms.bus import ZenohBus, make_config  # noqa: E402
from dms.config import load_config  # noqa: E402
from dms.daemon import Daemon  # noqa: E402
from dms.kernel import keys  # noqa: E402
from dms.kernel.clock import VirtualClock  # noqa: E402
from dms.kernel.messages import Decision, RobotCommand  # noqa: E402
from sim.adapters import daily_reminder, ensure_user  # noqa: E402
from sim.longterm import START, plan_visits  # noqa: E402
from sim.persona import load_persona, shipped_personas  # noqa: E402
from sim.robot import SimRobot  # noqa: E402
from sim.user import SimulatedUser  # noqa: E402

DAY_S = 86_400.0


def status_mb(field: str) -> float:
    """``field`` (VmRSS, VmHWM) of this process's /proc status, in MB."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith(field + ":"):
            return int(line.split()[1]) / 1024.0
    raise RuntimeError(f"no {field} in /proc/self/status")


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


class TappedBus(ZenohBus):
    """The daemon's Zenoh bus; what it publishes is also shown to ``tap`` (the person)."""

    def __init__(
        self, robot_id: str, config: Any, tap: Callable[[str, Mapping[str, Any]], None]
    ) -> None:
        super().__init__(robot_id, config)
        self.tap = tap

    def publish(self, key: str, payload: Mapping[str, Any]) -> None:
        super().publish(key, payload)
        self.tap(key, payload)


class Room:
    """Who is in front of the robot, and what they publish, on the virtual clock."""

    def __init__(self, clock: VirtualClock) -> None:
        self.clock = clock
        self.user: SimulatedUser | None = None
        self.absent: SimulatedUser | None = None
        """The last visitor, gone: their perception says nobody is there."""
        self._perceived: tuple[object, bytes] | None = None

    def hear(self, key: str, payload: Mapping[str, Any]) -> None:
        """What the daemon publishes, as the person in front sees and hears it."""
        user = self.user
        if user is None:
            return
        if key == keys.ROBOT_COMMAND:
            user.on_command(RobotCommand.model_validate(payload), self.clock.now())
        elif key == keys.DMS_DECISION:
            user.on_decision(Decision.model_validate(payload), self.clock.now())

    def perception(self) -> bytes:
        """The perception module's message now (encoded once while it does not change)."""
        someone = self.user or self.absent
        if someone is None:
            return b'{"present": false, "user_id": null, "ready": false, "engagement": null}'
        message = someone.perception()
        if self._perceived is None or self._perceived[0] is not message:
            self._perceived = (message, message.model_dump_json().encode())
        return self._perceived[1]


def settle(daemon: Daemon) -> None:
    """Let the background writes (profiles, agenda claims) catch up, as the real minutes
    between a live daemon's ticks let them: a week run in two minutes would otherwise
    pile them up in memory, and the figure would depend on thread timing."""
    profiles = daemon.stack.controller.deps.profiles
    if profiles is not None:
        profiles.writer.wait_idle(10.0)
    if daemon.stack.agenda is not None:
        daemon.stack.agenda.wait_idle(10.0)


def run(days: float, users: int, seed: int) -> dict[str, Any]:
    """Build the daemon, drive it through ``days`` of virtual time; the figures."""
    wall = time.perf_counter()
    tmp = tempfile.TemporaryDirectory(prefix="dms-week-")
    settings = load_config(
        db=f"sqlite:///{Path(tmp.name) / 'week.db'}",
        listen=[f"tcp/127.0.0.1:{free_port()}"],
        seed=seed,
        use_environment=False,
    )
    clock = VirtualClock(START)
    room = Room(clock)
    zenoh = settings.zenoh
    bus = TappedBus(
        settings.robot_id,
        make_config(zenoh.listen, zenoh.connect, zenoh.config_file),
        room.hear,
    )
    daemon = Daemon(
        settings,
        print_decisions=False,
        bus=bus,
        clock=clock,
        sim_robot=lambda robot_seed: SimRobot(rng_seed=robot_seed),
    )
    daemon.start()
    rss_ready = status_mb("VmRSS")
    built_s = time.perf_counter() - wall

    rng = random.Random(seed)
    names = [name for name in shipped_personas() if name != "demo"][:users]
    personas = [load_persona(name) for name in names]
    people = [SimulatedUser(p, random.Random(rng.random())) for p in personas]
    for person, persona in zip(people, personas, strict=True):
        ensure_user(daemon.stack, person.user_id, START)
        if daemon.stack.agenda is not None and persona.visits:
            first = persona.visits[0].at
            minute = first.hour * 60 + first.minute + 10
            daily_reminder(
                daemon.stack.agenda, person.user_id, minute // 60 % 24, minute % 60, START
            )
    visits = plan_visits(personas, max(1, int(days + 0.999)), rng)

    period = settings.controller.tick_period_s
    end_s = days * DAY_S
    next_tick = period
    next_day = DAY_S
    next_hour = 3600.0
    index = 0
    leave_at: float | None = None
    ticks = urgent_ticks = inputs = 0
    by_day: list[float] = []
    counters = daemon.stack.controller.counters
    decisions_before = counters.decisions

    def deliver(key: str, raw: bytes) -> None:
        nonlocal inputs
        inputs += 1
        daemon.on_input(key, raw)

    while True:
        t = clock.monotonic()
        upcoming = next_tick
        arrival = visits[index].start_s if index < len(visits) and leave_at is None else None
        if arrival is not None:
            upcoming = min(upcoming, arrival)
        if leave_at is not None:
            upcoming = min(upcoming, leave_at)
        user = room.user
        due = user.next_due() if user is not None else None
        if due is not None:
            upcoming = min(upcoming, (due - START).total_seconds())
        if upcoming > end_s:
            break
        if upcoming > t:
            clock.advance(upcoming - t)
            t = clock.monotonic()
        now = clock.now()
        if leave_at is not None and t >= leave_at:
            assert room.user is not None
            room.user.leave(now)
            room.absent, room.user, leave_at = room.user, None, None
            settle(daemon)
        elif arrival is not None and t >= arrival:
            visit = visits[index]
            index += 1
            room.user, leave_at = people[visit.user], visit.end_s
            room.user.arrive(now)
            deliver(keys.PERCEPTION_USER, room.perception())
        urgent = False
        user = room.user
        if user is not None and (due := user.next_due()) is not None and due <= now:
            for key, message in user.due(now):
                deliver(key, message.model_dump_json().encode())
                urgent = urgent or key in keys.URGENT_INPUTS
        if next_tick <= t:
            deliver(keys.PERCEPTION_USER, room.perception())
            daemon._run_tick(urgent=False)
            ticks += 1
            next_tick += period
        elif urgent:
            daemon._run_tick(urgent=True)
            urgent_ticks += 1
        if t >= next_hour:
            settle(daemon)
            next_hour += 3600.0
        if t >= next_day:
            by_day.append(round(status_mb("VmRSS"), 1))
            next_day += DAY_S
    decisions = counters.decisions - decisions_before
    rss_after = status_mb("VmRSS")
    peak = status_mb("VmHWM")
    daemon.close()
    tmp.cleanup()
    return {
        "benchmark": "week",
        "days": days,
        "users": names,
        "visits": index,
        "ticks": ticks,
        "urgent_ticks": urgent_ticks,
        "inputs": inputs,
        "decisions": decisions,
        "build_s": round(built_s, 2),
        "wall_s": round(time.perf_counter() - wall, 1),
        "rss_mb_at_ready": round(rss_ready, 1),
        "rss_mb_by_day": by_day,
        "rss_mb_after": round(rss_after, 1),
        "rss_mb_peak": round(peak, 1),
        "target_rss_mb_after_week": 150.0,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--days", type=float, default=7.0, help="virtual days (default 7)")
    parser.add_argument("--users", type=int, default=3, help="visiting users (default 3)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--quick", action="store_true", help="a simulated hour (smoke)")
    args = parser.parse_args()
    print(json.dumps(run(1 / 24 if args.quick else args.days, args.users, args.seed)))


if __name__ == "__main__":
    main()
