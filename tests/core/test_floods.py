"""Floods stay cheap: per-key rate caps on inputs and queries, a cap on the reports
that rejected messages cause, the bound on params names, and coalesced reloads.

The daemon's wiring is run over the in-memory bus on a virtual clock: a whole flood
arrives at one instant, and time moves only when the test says.
"""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from dms.config import load_config
from dms.daemon import Daemon
from dms.kernel import keys
from dms.kernel.clock import VirtualClock
from dms.kernel.errors import ConfigError
from dms.kernel.ports import RobotPort
from dms.local_bus import InMemoryBus
from dms.rate_caps import Drops, DropTally, RateCaps
from dms.reloader import Reloader


def test_a_cap_admits_its_rate_and_a_burst_then_drops_and_counts() -> None:
    caps = RateCaps({"request": 10.0})
    admitted = sum(caps.admit("request", 100.0 + i * 0.0001) for i in range(1000))
    assert admitted == 10  # the burst of one second; 0.1 s refills less than one token
    assert caps.dropped("request") == 1000 - admitted


def test_a_cap_refills_at_its_rate() -> None:
    caps = RateCaps({"perception/user": 50.0})
    t, admitted = 0.0, 0
    for _ in range(10 * 200):  # 10 s at 200 messages a second
        t += 0.005
        admitted += caps.admit("perception/user", t)
    assert 500 <= admitted <= 550  # 50/s for 10 s, plus the first burst


def test_keys_without_a_cap_are_always_admitted() -> None:
    caps = RateCaps({"request": 1.0})
    assert all(caps.admit("perception/touch", 5.0) for _ in range(1000))


def test_drops_are_reported_once_a_second_per_key_not_per_message() -> None:
    caps = RateCaps({"request": 5.0, "params/env": 5.0})
    for i in range(300):
        caps.admit("request", 10.0 + i / 1000)
    first = caps.due_reports(10.3)
    assert [key for key, _ in first] == ["request"]
    assert "dropped 294 messages" in first[0][1] and "5/s" in first[0][1]
    assert caps.due_reports(10.5) == []  # within the second: nothing more
    assert caps.due_reports(11.4) == []  # nothing dropped since: nothing to say
    for _ in range(20):  # the bucket is full again (5): 15 dropped
        caps.admit("request", 11.42)
    again = caps.due_reports(11.5)
    assert again == [("request", "rate cap 5/s: dropped 15 messages (309 since start)")]


def test_a_tally_hands_out_its_counts_once_an_interval() -> None:
    tally = DropTally()
    tally.add("params/env", 300)
    tally.add("params/env", 12)
    assert tally.due(5.0) == [Drops("params/env", 312, 312)]
    tally.add("params/env", 4)
    assert tally.due(5.5) == []  # within the second: kept for the next report
    assert tally.due(6.0) == [Drops("params/env", 4, 316)]
    assert tally.due(9.0) == []  # nothing new: nothing to say


def _robot(seed: int) -> RobotPort:
    from sim.robot import SimRobot

    return SimRobot(rng_seed=seed)


@pytest.fixture
def wired(tmp_path: Path) -> Iterator[tuple[Daemon, InMemoryBus, VirtualClock]]:
    """A started daemon over the in-memory bus, on a virtual clock."""
    settings = load_config(db=f"sqlite:///{tmp_path / 'dms.db'}", use_environment=False)
    bus, clock = InMemoryBus(), VirtualClock()
    daemon = Daemon(settings, print_decisions=False, bus=bus, clock=clock, sim_robot=_robot)
    daemon.start()
    try:
        yield daemon, bus, clock
    finally:
        daemon.close()


def _errors(bus: InMemoryBus, key: str) -> list[str]:
    return [str(r["error"]) for r in bus.messages(keys.DMS_ERRORS) if r["key"] == key]


def _count(line: str, after: str) -> int:
    return int(line.split(after, 1)[1].split()[0])


def test_a_flood_of_bad_objects_gives_a_bounded_number_of_reports(
    wired: tuple[Daemon, InMemoryBus, VirtualClock],
) -> None:
    daemon, bus, clock = wired
    flood = 5000
    for _ in range(flood):
        bus.inject(keys.PERCEPTION_OBJECTS, b'{"objects": "not a list"}')
    clock.advance(1.0)
    daemon._run_tick(urgent=False)
    lines = _errors(bus, keys.PERCEPTION_OBJECTS)
    one_by_one = [line for line in lines if not line.startswith(("rate cap", "report cap"))]
    rate = [line for line in lines if line.startswith("rate cap 100/s")]
    reports = [line for line in lines if line.startswith("report cap 20/s")]
    # a second of the cap admitted (100), 20 of them reported one by one, each drop summed
    assert len(one_by_one) == 20 and all(line.startswith("objects: ") for line in one_by_one)
    assert len(rate) == 1 and _count(rate[0], "dropped ") == flood - 100, rate
    assert len(reports) == 1 and _count(reports[0], "dropped ") == 100 - 20, reports
    assert len(lines) == 22  # not 5,000
    assert daemon.stack.inputs.counters.rejected == 100


def test_a_joints_flood_is_capped(wired: tuple[Daemon, InMemoryBus, VirtualClock]) -> None:
    daemon, bus, clock = wired
    accepted = daemon.stack.inputs.counters.by_key.get(keys.ROBOT_JOINTS, 0)
    for _ in range(3000):
        bus.inject(keys.ROBOT_JOINTS, {"positions": {"head": 0.1}})
    assert daemon.stack.inputs.counters.by_key[keys.ROBOT_JOINTS] - accepted == 200
    assert daemon.rate_caps.dropped(keys.ROBOT_JOINTS) == 2800
    clock.advance(1.0)
    daemon._run_tick(urgent=False)
    assert _errors(bus, keys.ROBOT_JOINTS) == [
        "rate cap 200/s: dropped 2800 messages (2800 since start)"
    ]


def test_every_queryable_is_capped_and_over_its_cap_answered_with_an_error(
    wired: tuple[Daemon, InMemoryBus, VirtualClock],
) -> None:
    daemon, bus, clock = wired
    for key in ("dms/state", "dms/behavior", "dms/config", "users/ann", "agenda/ann"):
        capped = "users/*" if key.startswith("users/") else key
        capped = "agenda/*" if key.startswith("agenda/") else capped
        rate = daemon.rate_caps.cap(capped)
        assert rate is not None, f"{key} has no rate cap"
        replies = [bus.query(key) for _ in range(int(rate) + 30)]
        refused = [body for ok, body in replies if not ok and "rate cap" in body["error"]]
        assert len(refused) == 30, (key, replies[-1])
        assert refused[0] == {"error": f"rate cap {rate:g}/s: refused"}
    clock.advance(1.0)
    daemon._run_tick(urgent=False)
    summed = [r for r in bus.messages(keys.DMS_ERRORS) if "dropped 30 messages" in r["error"]]
    assert sorted(r["key"] for r in summed) == sorted(
        ["dms/state", "dms/behavior", "dms/config", "users/*", "agenda/*"]
    )


def test_the_params_name_bound_drops_the_oldest_and_reports_once_with_the_count(
    wired: tuple[Daemon, InMemoryBus, VirtualClock],
) -> None:
    daemon, bus, clock = wired
    for batch in range(4):  # 1,024 distinct names in four messages
        names = {f"n{batch}_{i}": i for i in range(256)}
        bus.inject(keys.PARAMS_ENV, json.dumps(names).encode())
    assert _errors(bus, keys.PARAMS_ENV) == []  # nothing said per message
    clock.advance(1.0)
    daemon._run_tick(urgent=False)
    snapshot = daemon.stack.inputs.take(clock.monotonic())
    assert sorted(snapshot.env_params) == sorted(f"n3_{i}" for i in range(256))
    assert _errors(bus, keys.PARAMS_ENV) == [
        "more than 256 names: dropped the 768 set longest ago (768 since start)"
    ]
    clock.advance(5.0)
    daemon._run_tick(urgent=False)
    assert len(_errors(bus, keys.PARAMS_ENV)) == 1  # said once


def test_the_caps_name_input_keys_and_queryables_only(tmp_path: Path) -> None:
    config = tmp_path / "dms.toml"
    config.write_text('[inputs.rate_cap_per_s]\n"robots/x" = 5.0\n')
    with pytest.raises(ConfigError, match="'robots/x' is not an input key or a queryable"):
        load_config(config, use_environment=False)
    config.write_text('[inputs.rate_cap_per_s]\n"users/*" = 5.0\n')
    caps = load_config(config, use_environment=False).inputs.rate_caps()
    assert caps["users/*"] == 5.0 and set(keys.INPUT_KEYS) <= set(caps)
    assert {"perception/objects", "robot/joints", "robot/feedback"} <= set(caps)


def test_a_thousand_reload_requests_cost_at_most_two_reloads() -> None:
    running = threading.Event()
    release = threading.Event()
    calls: list[float] = []

    def slow_reload() -> list[tuple[str, str]]:
        calls.append(time.monotonic())
        running.set()
        release.wait(10)
        return []

    reports: list[tuple[str, str]] = []
    reloader = Reloader(slow_reload, lambda key, line: reports.append((key, line)))
    reloader.start()
    try:
        reloader.request()
        assert running.wait(10)
        for _ in range(1000):
            reloader.request()
        release.set()
        assert reloader.wait_idle(2, 10)
        assert not reloader.wait_idle(3, 0.3)  # no third reload for the 1,000 coalesced
        assert len(calls) == 2 and reports == []
    finally:
        release.set()
        reloader.stop()


def test_a_reload_that_raises_is_reported_and_the_worker_goes_on() -> None:
    outcomes: list[list[tuple[str, str]] | Exception] = [RuntimeError("disk gone"), []]

    def job() -> list[tuple[str, str]]:
        outcome = outcomes.pop(0)
        if isinstance(outcome, Exception):
            raise outcome
        return outcome

    reports: list[tuple[str, str]] = []
    reloader = Reloader(job, lambda key, line: reports.append((key, line)))
    reloader.start()
    try:
        reloader.request()
        assert reloader.wait_idle(1, 10)
        reloader.request()
        assert reloader.wait_idle(2, 10)
        assert reports == [("reload", "reload failed: RuntimeError: disk gone")]
    finally:
        reloader.stop()
