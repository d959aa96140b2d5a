"""Ctrl-C at any moment of ``dms run`` ends it quietly with 130, and ``dms --version``
answers without loading the decision stack.

Each case is a real process: SIGINT is sent right after it is spawned, while it imports
(the moment is an import line of ``python -X importtime``), while it sets up a fresh
database (its first log line) and once it is ready. Every wait is for a line on stderr.
The quiet exit starts with ``dms.cli.main``: Python's own start and the import of
``dms.cli`` (typer) come before it, a few tens of milliseconds. A signal that comes
while Python imports its own site module ends it with Python's "Fatal Python error"
and exit 1, before any code of the project runs: the first case allows that outcome,
and checks that nothing but Python's frozen modules had run.
"""

from __future__ import annotations

import gc
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.integration.harness import READY_TIMEOUT_S, StderrLines, free_port

pytestmark = pytest.mark.integration

INTERRUPTED = 130
"""The exit code after Ctrl-C (128 + SIGINT), as a shell reports it."""
PYTHON_START_INTERRUPTED = 1
"""Python's exit code when SIGINT comes while it imports its own site module, after it
has put in its handler and before it runs any code of the program (a few milliseconds)."""


_SPAWNED: list[subprocess.Popen[str]] = []


@pytest.fixture(autouse=True)
def _no_process_left() -> Iterator[None]:
    """A test that fails before its SIGINT leaves no daemon running behind it."""
    yield
    while _SPAWNED:
        proc = _SPAWNED.pop()
        if proc.poll() is None:
            proc.kill()
            proc.wait(10)


@pytest.fixture(autouse=True)
def _sigint_as_a_terminal_sends_it() -> Iterator[None]:
    """The daemons these cases spawn do not ignore SIGINT, even when the tests run
    where it is ignored (a job started in the background): a child inherits an ignored
    SIGINT, and Python keeps ignoring it until ``dms.cli.main`` takes it over, so a
    Ctrl-C in its first moment would be lost. Ctrl-C from a terminal finds it handled."""
    previous = signal.getsignal(signal.SIGINT)
    if previous == signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)


def spawn(tmp: Path, *python_flags: str) -> subprocess.Popen[str]:
    """``dms run`` on a fresh SQLite file in ``tmp`` and a free loopback port."""
    command = [sys.executable, *python_flags, "-m", "dms.cli", "run", "--quiet"]
    command += ["--db", str(tmp / "dms.db"), "--listen", f"tcp/127.0.0.1:{free_port()}"]
    command += ["--seed", "1", "--log-level", "info"]
    proc = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    _SPAWNED.append(proc)
    return proc


def interrupt(proc: subprocess.Popen[str], lines: StderrLines) -> tuple[int, str]:
    """SIGINT now; the exit code and everything the process wrote on stderr."""
    proc.send_signal(signal.SIGINT)
    try:
        code = proc.wait(30)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait(10)
        raise AssertionError("still running 30 s after SIGINT:\n" + lines.text()) from None
    return code, lines.text()


def _before_the_project(frame: str) -> bool:
    """A traceback line of Python's start: frozen, a .pth line, or an installed file."""
    return any(mark in frame for mark in ('File "<frozen ', 'File "<string>"', "/site-packages/"))


def test_ctrl_c_right_after_spawn_is_quiet(tmp_path: Path) -> None:
    proc = spawn(tmp_path)
    code, stderr = interrupt(proc, StderrLines(proc))
    if code == PYTHON_START_INTERRUPTED:
        # Python's own start (its site module) took the signal: none of the project's
        # code had run, every frame Python prints is one of its own frozen modules or
        # the installed packages' start-up lines (a .pth file, an editable install's
        # finder) that the site module runs.
        assert "Fatal Python error: init_import_site" in stderr, stderr
        frames = [line for line in stderr.splitlines() if line.strip().startswith("File ")]
        assert frames and all(_before_the_project(frame) for frame in frames), stderr
        return
    # Before Python has put in its handler the signal's default action ends the process,
    # which a shell reports as 130 too.
    assert code in (INTERRUPTED, -signal.SIGINT), stderr
    assert "Traceback" not in stderr, stderr


@pytest.mark.parametrize("module", ["sqlalchemy.orm", "activities.library", "dms.daemon"])
def test_ctrl_c_while_importing_is_quiet(tmp_path: Path, module: str) -> None:
    proc = spawn(tmp_path, "-X", "importtime")
    lines = StderrLines(proc)
    lines.wait_for(lambda line: line.startswith("import time:") and line.strip().endswith(module))
    code, stderr = interrupt(proc, lines)
    assert code == INTERRUPTED, stderr
    assert "Traceback" not in stderr, stderr


def test_ctrl_c_while_the_database_is_made_is_quiet_and_leaves_it_usable(
    tmp_path: Path,
) -> None:
    proc = spawn(tmp_path)
    lines = StderrLines(proc)
    lines.wait_for(lambda line: line.strip() != "")  # the migrations log first
    code, stderr = interrupt(proc, lines)
    assert code == INTERRUPTED, stderr
    assert "Traceback" not in stderr, stderr

    again = spawn(tmp_path)
    again_lines = StderrLines(again)
    again_lines.wait_for("ready on", READY_TIMEOUT_S)
    code, stderr = interrupt(again, again_lines)
    assert code == INTERRUPTED, stderr


def test_ctrl_c_once_ready_stops_cleanly_with_130(tmp_path: Path) -> None:
    proc = spawn(tmp_path)
    lines = StderrLines(proc)
    lines.wait_for("ready on", READY_TIMEOUT_S)
    code, stderr = interrupt(proc, lines)
    assert code == INTERRUPTED, stderr
    assert "Traceback" not in stderr, stderr


def test_without_rules_files_it_is_ready_without_the_rules_language(tmp_path: Path) -> None:
    """What only some robots use loads when they use it: the rules language (a robot
    with rules files), the studio's YAML writer (a saved behavior), not on the start."""
    proc = spawn(tmp_path, "-X", "importtime")
    lines = StderrLines(proc)
    lines.wait_for("ready on", READY_TIMEOUT_S)
    code, stderr = interrupt(proc, lines)
    assert code == INTERRUPTED, stderr
    before_ready = stderr.split("ready on")[0].splitlines()
    imported = {line.rsplit("|", 1)[1].strip() for line in before_ready if "import time:" in line}
    assert {"dms.daemon", "dms.studio.daemon_try"} <= imported  # the log is read right
    assert not {"lark", "dms.rules", "ruamel.yaml"} & imported


def test_version_and_help_load_no_package_of_the_stack() -> None:
    heavy = ("numpy", "sqlalchemy", "zenoh", "pydantic", "activities", "memory", "agenda")
    code = (
        "import sys\nfrom dms.cli import main\n"
        "for argv in (['--version'], ['--help']):\n"
        "    assert main(argv) == 0\n"
        f"print(sorted(m for m in {heavy!r} if m in sys.modules))"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=True
    )
    assert done.stdout.strip().splitlines()[-1] == "[]"


def test_a_run_refused_before_ready_leaves_the_garbage_collector_on(tmp_path: Path) -> None:
    """``dms run`` starts with the collector off until ready; a caller in the same
    process whose run is refused (here a configuration file that does not parse) gets
    it back on."""
    from dms.cli import main

    bad = tmp_path / "dms.toml"
    bad.write_text("seed = \n")
    assert gc.isenabled()
    assert main(["run", "--config", str(bad), "--db", str(tmp_path / "dms.db")]) == 1
    assert gc.isenabled()
