"""The check of tests/conftest.py fails a test that leaves a thread or a process running.

Each case runs a small test file in its own pytest process, with the check as the
project's tests have it, and reads the outcome.
"""

from __future__ import annotations

import contextlib
import os
import signal
from pathlib import Path

import pytest

pytest_plugins = ["pytester"]

CONFTEST = (Path(__file__).parent / "conftest.py").read_text(encoding="utf-8")


def _run(pytester: pytest.Pytester, body: str) -> pytest.RunResult:
    pytester.makeconftest(CONFTEST)
    pytester.makepyfile(test_inner=body)
    return pytester.runpytest_subprocess("-q", "-p", "no:cacheprovider")


def test_a_thread_left_running_fails_the_test(pytester: pytest.Pytester) -> None:
    result = _run(
        pytester,
        """
import threading

STOP = threading.Event()

def test_leaves_a_thread():
    threading.Thread(target=STOP.wait, name="forgotten", daemon=True).start()
""",
    )
    result.assert_outcomes(passed=1, errors=1)
    result.stdout.fnmatch_lines(["*the test left threads still running: forgotten*"])


def test_a_thread_that_is_ending_is_waited_for(pytester: pytest.Pytester) -> None:
    result = _run(
        pytester,
        """
import threading

def test_tells_its_thread_to_stop():
    stop = threading.Event()
    thread = threading.Thread(target=stop.wait, name="ending")
    thread.start()
    stop.set()  # not joined: the check's grace lets it end
""",
    )
    result.assert_outcomes(passed=1)


def test_a_child_process_left_running_fails_the_test(pytester: pytest.Pytester) -> None:
    pid_file = pytester.path / "child.pid"
    result = _run(
        pytester,
        f"""
import subprocess
from pathlib import Path

def test_leaves_a_process():
    child = subprocess.Popen(["sleep", "60"])
    Path({str(pid_file)!r}).write_text(str(child.pid))
""",
    )
    try:
        result.assert_outcomes(passed=1, errors=1)
        result.stdout.fnmatch_lines(["*child processes still running: * (sleep 60)*"])
    finally:
        if pid_file.exists():
            with contextlib.suppress(ProcessLookupError):
                os.kill(int(pid_file.read_text()), signal.SIGKILL)


def test_a_process_ended_and_reaped_passes(pytester: pytest.Pytester) -> None:
    result = _run(
        pytester,
        """
import subprocess

def test_ends_its_process():
    child = subprocess.Popen(["sleep", "60"])
    child.kill()
    child.wait(10)
""",
    )
    result.assert_outcomes(passed=1)
