"""The reloader's deadline and its stop: a reload that never ends is reported and never
holds the daemon at exit (the integration tests run the real rules and behaviors)."""

from __future__ import annotations

import threading
import time

from dms.reloader import Reloader

Reports = list[tuple[str, str]]


def _blocking_job(release: threading.Event, running: threading.Event) -> Reports:
    running.set()
    release.wait(30)
    return [("rules", "late problem")]


def test_a_reload_past_its_deadline_is_reported_and_the_next_one_waits_for_it() -> None:
    release, running = threading.Event(), threading.Event()
    reported = threading.Event()
    reports: Reports = []

    def report(key: str, line: str) -> None:
        reports.append((key, line))
        reported.set()

    reloader = Reloader(lambda: _blocking_job(release, running), report, deadline_s=0.2)
    reloader.start()
    try:
        reloader.request()
        assert reported.wait(10)
        assert reports == [
            (
                "reload",
                "reload still running after 0.2 s; the previous rules and behaviors stay "
                "in force until it ends, and later reloads wait for it",
            )
        ]
        assert reloader.reloads == 0
        release.set()
        assert reloader.wait_idle(1, 10)
        assert reports[1:] == [("rules", "late problem")]
    finally:
        release.set()
        reloader.stop()


def test_stop_during_a_reload_does_not_wait_for_it_nor_report_after() -> None:
    release, running = threading.Event(), threading.Event()
    reports: Reports = []
    reloader = Reloader(
        lambda: _blocking_job(release, running),
        lambda key, line: reports.append((key, line)),
        deadline_s=60.0,
    )
    reloader.start()
    reloader.request()
    assert running.wait(10)
    started = time.monotonic()
    reloader.stop(timeout_s=5.0)
    assert time.monotonic() - started < 0.5
    release.set()  # the job ends after the stop: nothing is reported any more
    assert not reloader.wait_idle(1, 0.3)
    assert reports == []
