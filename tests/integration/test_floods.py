"""The daemon under floods, as a peer on the network sends them: one real ``dms run``
per test, real Zenoh sessions on 127.0.0.1.

- the reload flood and SIGTERM under a request flood;
- a flood over a rate cap (``perception/touch``, ``robot/joints``): dropped unread,
  summed once a second, state keeps flowing;
- a flood of bad ``perception/objects``: a bounded number of ``dms/errors`` reports;
- a flood of made-up ``params/env`` names: the daemon's memory stays flat, and the
  names dropped for the bound are reported once a second with their count.

Every wait is for a message or a token with a deadline; every flood is bounded in count
and time.
"""

from __future__ import annotations

import itertools
import json
import re
import signal
import threading
import time
from pathlib import Path
from typing import Any

import pytest
import zenoh

from tests.integration.harness import Collector, DaemonProcess, paced, put, running_daemon
from tests.integration.hostile import (
    MAX_STATE_GAP_S,
    SENTINELS_SENT,
    Reports,
    assert_alive,
    caps,
    flood,
    is_sentinel,
    longest_gap,
    sentinel,
    state_after,
    ts,
)

pytestmark = pytest.mark.integration

# ---------------------------------------------------------------- the reload flood

RELOADS = 2000
RELOAD_FLOOD_S = 4.0


def test_a_reload_flood_is_coalesced_and_sigterm_under_a_request_flood_exits_within_1s(
    tmp_path: Path,
) -> None:
    with running_daemon(tmp_path, caps(10000.0, ["request"])) as (daemon, session):
        states = Collector(session, "robots/mini/dms/state")
        reports = Reports(session)
        first = states.wait_count(1)[-1]
        assert first["reloads"] == 0
        mark = states.mark() - 1
        reload = {"action": "reload_rules", "by": "flood"}
        started = time.monotonic()
        flood(session, "request", itertools.repeat(reload, RELOADS), RELOADS / RELOAD_FLOOD_S)
        flood_s = time.monotonic() - started
        assert flood_s < RELOAD_FLOOD_S + 1.0, flood_s
        # every request has been read once the sentinel is; the last reload it asked for
        # ends well within 2 s of the daemon's clock
        end = sentinel(session, reports, "request")
        settled = state_after(states, ts(reports.all()[end]) + 2.0)
        during = states.messages[mark : states.mark()]
        assert longest_gap(during) <= MAX_STATE_GAP_S, (
            f"longest dms/state gap {longest_gap(during):.3f}s during {RELOADS} reloads"
        )
        reloads = settled["reloads"]
        assert 1 <= reloads <= RELOADS // 10, f"{reloads} reloads for {RELOADS} requests"
        assert [r for r in reports.all() if r["key"] in ("rules", "behaviors", "reload")] == []
        assert_alive(daemon, session, states)

        # SIGHUPs in a burst while requests come: only enqueued, coalesced, the loop on
        before = state_after(states, time.time())["reloads"]
        assert daemon.proc is not None
        for _ in range(HUPS):
            daemon.proc.send_signal(signal.SIGHUP)
        states.wait_for(lambda s: s["reloads"] > before, start=states.mark() - 1)
        assert_alive(daemon, session, states)
        code, exit_s = stopped_under_a_request_flood(daemon, session, states, signal.SIGTERM)
    assert code == 0, daemon.log.read_text()[-3000:]
    assert exit_s <= STOP_S, f"SIGTERM to exit took {exit_s:.2f}s under a 500/s request flood"


def test_sigint_under_a_request_flood_exits_130_within_1s(tmp_path: Path) -> None:
    with running_daemon(tmp_path, caps(10000.0, ["request"])) as (daemon, session):
        states = Collector(session, "robots/mini/dms/state")
        states.wait_count(1)
        code, exit_s = stopped_under_a_request_flood(daemon, session, states, signal.SIGINT)
    assert code == 130, daemon.log.read_text()[-3000:]
    assert exit_s <= STOP_S, f"SIGINT to exit took {exit_s:.2f}s under a 500/s request flood"
    assert "stopped (inputs" in daemon.log.read_text()  # each step's time, for an operator


HUPS = 200
STOP_S = 1.0
"""A signal to the end of the process, under a flood: a supervisor's stop is at once."""


def stopped_under_a_request_flood(
    daemon: DaemonProcess, session: zenoh.Session, states: Collector, signum: int
) -> tuple[int, float]:
    """Flood 500 requests a second (reloads, starts, cancels), send ``signum`` after a
    second of it, and return the exit status and how long the process took to end."""
    stop, sent = threading.Event(), [0]
    requests = itertools.cycle(
        [
            {"action": "reload_rules", "by": "flood"},
            {"action": "start", "activity": "jokes", "by": "flood"},
            {"action": "cancel", "by": "flood"},
        ]
    )
    flooder = threading.Thread(
        target=flood, args=(session, "request", requests, 500.0, stop, sent), daemon=True
    )
    flooder.start()
    try:
        state_after(states, time.time() + 1.0)  # a second of flood, the daemon ticking
        assert sent[0] >= 250 and flooder.is_alive(), sent
        assert daemon.proc is not None
        signalled = time.monotonic()
        daemon.proc.send_signal(signum)
        code = daemon.proc.wait(20)
        exit_s = time.monotonic() - signalled
        assert flooder.is_alive(), "the flood must still run at the signal"
    finally:
        stop.set()
        flooder.join(10)
    return code, exit_s


# ---------------------------------------------------------------- 4. over the rate cap

FLOOD = 3000
FLOODS = [
    # (key, a valid message, dms/config.py's default cap: a burst is a second of it)
    ("perception/touch", {"part": "head", "kind": "caress"}, 50.0),
    ("robot/joints", {"positions": {"head": 0.1, "neck": -0.2}}, 200.0),
]
SUMMARY = re.compile(r"^rate cap (\d+(?:\.\d+)?)/s: dropped (\d+) messages \((\d+) since start\)$")


@pytest.mark.parametrize(("key", "message", "cap"), FLOODS, ids=[key for key, *_ in FLOODS])
def test_a_flood_over_the_default_cap_is_dropped_counted_and_summed_once_a_second(
    tmp_path: Path, key: str, message: dict[str, Any], cap: float
) -> None:
    with running_daemon(tmp_path) as (daemon, session):
        states = Collector(session, "robots/mini/dms/state")
        reports = Reports(session)
        states.wait_count(1)
        mark, first_report = states.mark() - 1, reports.mark()
        sentinels_before = SENTINELS_SENT[key]
        started = time.monotonic()
        for _ in range(FLOOD):  # at full speed
            put(session, key, message)
        # A sentinel on the same key may itself be dropped by the cap: ask again until one
        # is read. Each is malformed (reported when admitted, counted when dropped).
        end = None
        while end is None:
            try:
                end = sentinel(session, reports, key, first_report, 2.0)
            except AssertionError:
                assert time.monotonic() - started < 30, "no sentinel was admitted in 30 s"
        window_s = time.monotonic() - started
        # every drop is summed in a report at most a second (and a tick) later
        state_after(states, ts(reports.all()[end]) + 2.0)
        during = states.messages[mark : states.mark()]

        on_key = reports.on(key, first_report)
        summaries = [SUMMARY.match(r["error"]) for r in on_key if r["error"].startswith("rate")]
        others = [r for r in on_key if not r["error"].startswith("rate")]
        assert summaries and all(summaries), on_key[:5]
        assert len(summaries) <= window_s + 4, (len(summaries), window_s)  # not 3,000 lines
        assert {float(m.group(1)) for m in summaries if m} == {cap}
        dropped = [int(m.group(2)) for m in summaries if m]
        totals = [int(m.group(3)) for m in summaries if m]
        assert totals == list(itertools.accumulate(dropped)), (dropped, totals)
        # what was not dropped was admitted: the flood plus the sentinels that got in
        sentinels_sent = SENTINELS_SENT[key] - sentinels_before
        admitted = FLOOD + sentinels_sent - totals[-1]
        assert others and all(is_sentinel(r) for r in others), others[:5]
        admitted_flood = admitted - len(others)
        burst = cap * 1.0
        assert burst <= admitted_flood <= burst + cap * window_s + 1, (
            f"{admitted_flood} of {FLOOD} messages admitted in {window_s:.2f}s"
            f" under a cap of {cap:g}/s, burst {burst:g}"
        )
        assert longest_gap(during) <= MAX_STATE_GAP_S, longest_gap(during)
        assert_alive(daemon, session, states)
        assert daemon.terminate() == 0


# ---------------------------------------------------------------- 5. reports and names

BAD_OBJECTS = 5000
OBJECTS_CAP = 100.0  # dms/config.py's defaults
REPORTS_CAP = 20.0
CAP_LINE = re.compile(r"^(rate|report) cap [\d.]+/s: dropped (\d+) (?:messages|reports) ")


def _accounted(reports: list[dict[str, Any]]) -> int:
    """Messages a key's reports account for: one per report of a rejection, plus the
    counts of the rate cap's and the report cap's summaries."""
    total = 0
    for report in reports:
        summary = CAP_LINE.match(report["error"])
        total += int(summary.group(2)) if summary else 1
    return total


def test_a_flood_of_bad_objects_gives_a_bounded_number_of_reports(tmp_path: Path) -> None:
    with running_daemon(tmp_path) as (daemon, session):
        states = Collector(session, "robots/mini/dms/state")
        reports = Reports(session)
        states.wait_count(1)
        first_report = reports.mark()
        log_before = daemon.log.stat().st_size
        bad = json.dumps({"objects": [{"name": "cup", "pose": "on the table"}]}).encode()
        started = time.monotonic()
        for _ in range(BAD_OBJECTS):  # at full speed
            put(session, "perception/objects", bad)
        # each message is either dropped by the rate cap, reported, or dropped by the
        # report cap: wait until the reports account for all of them
        key = "perception/objects"
        deadline = time.monotonic() + 60
        while _accounted(reports.on(key, first_report, seen := reports.mark())) < BAD_OBJECTS:
            assert time.monotonic() < deadline, _accounted(reports.on(key, first_report))
            reports.wait_for(lambda r: r["key"] == key, timeout=10, start=seen)
        window_s = time.monotonic() - started
        on_key = reports.on(key, first_report)
        assert _accounted(on_key) == BAD_OBJECTS
        one_by_one = [r for r in on_key if not CAP_LINE.match(r["error"])]
        summaries = len(on_key) - len(one_by_one)
        assert all(r["error"].startswith("objects.0.pose") for r in one_by_one), one_by_one[:3]
        bound = REPORTS_CAP * (1 + window_s) + 2 * (window_s + 3)
        assert REPORTS_CAP <= len(on_key) <= bound, (
            f"{len(on_key)} reports ({summaries} summaries) for {BAD_OBJECTS} bad messages"
            f" in {window_s:.2f}s"
        )
        logged = daemon.log.stat().st_size - log_before
        assert logged < 400 * len(on_key) + 10_000, f"{logged} bytes of log"
        assert_alive(daemon, session, states)
        assert daemon.terminate() == 0


def _names(first: int, count: int, width: int = 60) -> dict[str, str]:
    """``count`` made-up params names from number ``first`` on, ``width`` long each."""
    return {f"n{number:0{width - 1}d}": "v" * 100 for number in range(first, first + count)}


NAME_BOUND = 256  # dms/config.py's default
NAME_LINE = re.compile(
    r"^more than (\d+) names: dropped the (\d+) set longest ago \((\d+) since start\)$"
)


def _dropped_names(reports: Reports, start: int) -> list[tuple[int, int]]:
    """(count, total) of each report of names dropped for the bound."""
    found = [NAME_LINE.match(r["error"]) for r in reports.on("params/env", start)]
    return [(int(m.group(2)), int(m.group(3))) for m in found if m]


def _wait_names_dropped(reports: Reports, start: int, total: int, timeout: float = 30) -> None:
    """Wait for the report whose total since start is ``total``."""
    reports.wait_for(
        lambda r: (m := NAME_LINE.match(r["error"])) is not None and int(m.group(3)) >= total,
        timeout=timeout,
        start=start,
    )


def test_the_params_name_bound_drops_the_oldest_and_reports_it_once(tmp_path: Path) -> None:
    with running_daemon(tmp_path) as (daemon, session):
        states = Collector(session, "robots/mini/dms/state")
        reports = Reports(session)
        states.wait_count(1)
        first_report = reports.mark()
        put(session, "params/env", _names(0, NAME_BOUND))
        put(session, "params/env", _names(NAME_BOUND, NAME_BOUND))
        _wait_names_dropped(reports, first_report, NAME_BOUND)
        # two more seconds of the daemon's clock: nothing more is said
        end = sentinel(session, reports, "params/env", first_report)
        state_after(states, ts(reports.all()[end]) + 2.0)
        assert _dropped_names(reports, first_report) == [(NAME_BOUND, NAME_BOUND)]
        assert reports.on("params/env", first_report)[0]["error"].startswith(
            f"more than {NAME_BOUND} names: "
        )
        assert_alive(daemon, session, states)
        assert daemon.terminate() == 0


def _rss_kib(pid: int) -> int:
    """The process's resident memory (``VmRSS`` of /proc/PID/status), in KiB."""
    status = Path(f"/proc/{pid}/status").read_text()
    return int(re.search(r"^VmRSS:\s+(\d+) kB$", status, re.MULTILINE).group(1))  # type: ignore[union-attr]


NAMES_RATE = 40.0  # messages a second: under params/env's cap of 50, so none is dropped
WARM_UP_S = 3.0
FLOOD_S = 12.0
RSS_MARGIN_KIB = 20 * 1024


def _name_flood(session: zenoh.Session, first_message: int, seconds: float) -> int:
    """Messages of 256 new names each at :data:`NAMES_RATE` for ``seconds``; how many."""
    count = int(NAMES_RATE * seconds)
    batches = (
        _names(n * NAME_BOUND, NAME_BOUND) for n in range(first_message, first_message + count)
    )
    for batch in paced(batches, NAMES_RATE):
        put(session, "params/env", batch)
    return count


@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="needs /proc")
def test_a_flood_of_made_up_params_names_keeps_the_daemon_memory_flat(tmp_path: Path) -> None:
    with running_daemon(tmp_path) as (daemon, session):
        assert daemon.proc is not None
        states = Collector(session, "robots/mini/dms/state")
        reports = Reports(session)
        states.wait_count(1)
        first_report = reports.mark()
        # a warm-up that fills the bound (and the allocator's pools) once
        sent = _name_flood(session, 0, WARM_UP_S)
        _wait_names_dropped(reports, first_report, (sent - 1) * NAME_BOUND)
        before = _rss_kib(daemon.proc.pid)
        flooded = _name_flood(session, sent, FLOOD_S)
        sent += flooded
        _wait_names_dropped(reports, first_report, (sent - 1) * NAME_BOUND)
        after = _rss_kib(daemon.proc.pid)
        assert after - before <= RSS_MARGIN_KIB, (
            f"VmRSS {before} -> {after} KiB over {flooded * NAME_BOUND} new names"
        )
        dropped = _dropped_names(reports, first_report)
        assert sum(count for count, _ in dropped) == (sent - 1) * NAME_BOUND
        assert len(dropped) <= WARM_UP_S + FLOOD_S + 10  # once a second, not per message
        assert_alive(daemon, session, states)
        assert daemon.terminate() == 0
