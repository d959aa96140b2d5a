"""Floods of valid messages stay cheap: per-key rate caps and coalesced reloads."""

from __future__ import annotations

import threading
import time

from dms.rate_caps import RateCaps
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
