"""Reloads of the rules and behaviors, coalesced and off the tick thread.

SIGHUP, ``reload_rules`` requests and saved files (:mod:`dms.watch`) only raise a flag;
one worker thread reads and compiles the files and swaps them in (each of
:class:`~dms.rules.LiveRules` and :class:`~activities.BehaviorLibrary` swaps its new
version in with one assignment, so a tick sees either the old or the new version, never
half of one). Requests that arrive while a reload runs are served by one more reload
after it, and reloads start at most every :data:`MIN_INTERVAL_S`: a flood of a thousand
requests a second costs four reloads a second, and the 2 Hz loop never waits for a
compile.

A reload cannot be interrupted (it runs Python code that swaps objects in), so it is
watched instead: one still running after :data:`DEADLINE_S` is reported on ``dms/errors``
and in the log, and stopping the daemon never waits for it (the thread is a daemon
thread, dropped at exit).
"""

from __future__ import annotations

import contextlib
import logging
import queue
import threading
import time
from collections.abc import Callable

log = logging.getLogger(__name__)

MIN_INTERVAL_S = 0.25
"""A reload waits this long after the start of the previous one (a lone request: none)."""

DEADLINE_S = 10.0
"""A reload still running after this long is reported (the verifier and the YAML loader
bound their work, so it takes a folder far larger than a robot's to get there)."""

ReloadJob = Callable[[], list[tuple[str, str]]]
"""Does one reload; returns ``(key, problem)`` lines for ``dms/errors`` (empty: all in force)."""


class Reloader:
    """One worker thread; :meth:`request` is cheap and safe from any thread or handler."""

    def __init__(
        self,
        job: ReloadJob,
        report: Callable[[str, str], None],
        min_interval_s: float = MIN_INTERVAL_S,
        deadline_s: float = DEADLINE_S,
    ) -> None:
        self._job = job
        self._min_interval_s = min_interval_s
        self._deadline_s = deadline_s
        self._busy = threading.Event()
        self._report = report
        self._calls: queue.SimpleQueue[None] = queue.SimpleQueue()
        """One word a request or the stop: a ``SimpleQueue``'s ``put`` is reentrant, so
        SIGHUP's handler can ask while the main thread is inside the queue's own code (a
        ``threading.Event`` there deadlocks on its lock)."""
        self._stopped = False
        self._thread = threading.Thread(target=self._run, name="dms-reload", daemon=True)
        self.requests = 0
        self.reloads = 0
        self._idle = threading.Condition()

    def start(self) -> None:
        self._thread.start()

    def request(self) -> None:
        """Ask for a reload; coalesced with every other request not yet served. Safe in
        a signal handler: it only enqueues."""
        self.requests += 1
        self._calls.put(None)

    def _run(self) -> None:
        last_start = -self._min_interval_s
        while True:
            self._calls.get()
            # Not before the interval is over; what comes meanwhile joins this reload.
            while (
                not self._stopped
                and (wait := last_start + self._min_interval_s - time.monotonic()) > 0
            ):
                with contextlib.suppress(queue.Empty):
                    self._calls.get(timeout=wait)
            with contextlib.suppress(queue.Empty):
                while True:
                    self._calls.get_nowait()
            if self._stopped:
                return
            last_start = time.monotonic()
            watch = threading.Timer(self._deadline_s, self._overdue)
            watch.daemon = True
            self._busy.set()
            watch.start()
            try:
                problems = self._job()
            except Exception as error:  # a reload must never take the daemon down
                log.exception("reload failed")
                problems = [("reload", f"reload failed: {type(error).__name__}: {error}")]
            finally:
                watch.cancel()
                self._busy.clear()
            if self._stopped:  # the daemon is closing: nowhere to report to
                return
            with self._idle:
                self.reloads += 1
                self._idle.notify_all()
            for key, problem in problems:
                self._report(key, problem)
            if not problems:
                log.info("rules and behaviors reloaded")

    def _overdue(self) -> None:
        """The watch's timer: this reload is past its deadline (it goes on regardless)."""
        if self._stopped:
            return
        log.warning("reload still running after %g s", self._deadline_s)
        self._report(
            "reload",
            f"reload still running after {self._deadline_s:g} s; the previous rules and "
            "behaviors stay in force until it ends, and later reloads wait for it",
        )

    def wait_idle(self, reloads: int, timeout_s: float) -> bool:
        """Wait until at least ``reloads`` reloads have finished (for tests and benchmarks)."""
        with self._idle:
            return self._idle.wait_for(lambda: self.reloads >= reloads, timeout_s)

    def stop(self, timeout_s: float = 1.0) -> None:
        """Stop the worker; an idle one ends at once. A reload under way is not waited
        for: it finishes in its own time, or is dropped at exit (a daemon thread)."""
        self._stopped = True
        self._calls.put(None)
        if self._busy.is_set():
            log.info("stopping during a reload: not waiting for it")
        elif self._thread.is_alive():
            self._thread.join(timeout_s)
