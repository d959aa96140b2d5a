"""What every test shares: a check that it leaves no thread or child process behind.

A test that starts a daemon, a writer, a Zenoh session or a background job must end
them: a thread or a process left running keeps working into the next tests (a writer
still writing, a daemon still answering on its port), makes their timings and their
failures someone else's, and grows the run until it stalls.
"""

from __future__ import annotations

import glob
import os
import select
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

GRACE_S = 3.0
"""How long a test's threads and children may take to end after it (a thread told to
stop finishes its last step; a killed process is reaped): longer is a leak."""


def _module_owned() -> tuple[set[int], set[threading.Thread]]:
    """The processes (and their output's readers) a module's fixture owns, as its tests
    registered them in ``tests/processes.py`` (read from ``sys.modules``: a test session
    that never imports it, such as the leak check's own inner sessions, has none)."""
    processes = sys.modules.get("tests.processes")
    if processes is None:
        return set(), set()
    return processes.MODULE_OWNED, processes.MODULE_THREADS


LOOP_EXECUTOR = "asyncio_"
"""The name of an event loop's default executor's threads (``asyncio_0``...)."""


def _threads() -> set[threading.Thread]:
    """The Python threads that run code of ours.

    Two kinds are left out. A thread Python did not start (Zenoh's runtime calling back
    into Python: a subscriber's handler, a query's reply) appears as a ``_DummyThread``
    and stays listed for as long as the process lives: it belongs to the runtime, which
    lives as long as the process, and there is nothing to end. An event loop's default
    executor starts its threads on first use and keeps them until the loop closes: the
    loop of Playwright's synchronous API, which a module's browser fixture holds, starts
    one in the first test that opens a page, and the fixture ends it after the module.
    """
    return {
        thread
        for thread in threading.enumerate()
        if thread.is_alive()
        and thread not in _module_owned()[1]
        and not isinstance(thread, threading._DummyThread)
        and not thread.name.startswith(LOOP_EXECUTOR)
    }


def _state(pid: int) -> str | None:
    """A process's state letter (``Z``: ended, not yet reaped); None when it is gone."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    return stat[stat.rindex(")") + 2 :].split()[0]


def _children() -> set[int]:
    """The running child processes of this process (an ended one, not reaped, is none)."""
    pids: set[int] = set()
    for path in glob.glob(f"/proc/{os.getpid()}/task/*/children"):
        try:
            pids.update(int(pid) for pid in Path(path).read_text().split())
        except OSError:
            continue  # the thread ended meanwhile
    return {pid for pid in pids if _state(pid) not in (None, "Z")}


def _describe(pid: int) -> str:
    try:
        command = Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").strip()
    except OSError:
        return str(pid)
    return f"{pid} ({command.decode(errors='replace')[:120]})"


def _wait_for_exit(pid: int, timeout: float) -> None:
    """Wait until ``pid`` ends (its pidfd becomes readable), at most ``timeout``."""
    try:
        fd = os.pidfd_open(pid)
    except OSError:
        return  # gone already
    try:
        select.select([fd], [], [], max(0.0, timeout))
    finally:
        os.close(fd)


@pytest.fixture(autouse=True)
def no_thread_or_process_left() -> Iterator[None]:
    """Fail the test that leaves a thread or a child process running after it."""
    threads, children = _threads(), _children()
    yield
    deadline = time.monotonic() + GRACE_S
    for thread in _threads() - threads:
        thread.join(max(0.0, deadline - time.monotonic()))
    owned = _module_owned()[0]
    for pid in _children() - children - owned:
        _wait_for_exit(pid, deadline - time.monotonic())
    left = sorted(thread.name for thread in _threads() - threads)
    running = sorted(_children() - children - owned)
    problems = []
    if left:
        problems.append(f"threads still running: {', '.join(left)}")
    if running:
        problems.append(f"child processes still running: {', '.join(map(_describe, running))}")
    if problems:
        pytest.fail(f"the test left {'; '.join(problems)} (end them in the test)")
