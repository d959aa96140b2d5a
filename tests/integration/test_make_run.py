"""``make run`` as a newcomer types it: in a fresh clone, in a terminal.

It shows the install as it goes, runs the demo until Ctrl-C, exits 0 then, and keeps
the demo's visitor out of the user's default database (``XDG_DATA_HOME`` points at a
temporary folder that must stay empty). The terminal is a pseudo-terminal, so Ctrl-C is
the byte a keyboard sends, delivered by the terminal to its foreground job.
"""

from __future__ import annotations

import os
import pty
import re
import select
import subprocess
import time
from pathlib import Path

import pytest

from tests.integration.harness import free_port

pytestmark = [pytest.mark.integration, pytest.mark.slow]

ROOT = Path(__file__).resolve().parents[2]
INSTALL_TIMEOUT_S = 900.0
"""The first run creates .venv and installs the runtime (pip's cache makes it minutes at
most; a cold one downloads about 300 MB)."""
DECISION = re.compile(rb"\d\d:\d\d:\d\d\.\d{3} start +\w+ \[")
CTRL_C = b"\x03"


def _read_until(fd: int, pattern: re.Pattern[bytes], seen: bytearray, timeout: float) -> bool:
    """Read the terminal into ``seen`` until ``pattern`` shows or it closes; True if shown."""
    deadline = time.monotonic() + timeout
    while not pattern.search(seen):
        left = deadline - time.monotonic()
        if left <= 0:
            return False
        ready, _, _ = select.select([fd], [], [], left)
        if not ready:
            continue
        try:
            chunk = os.read(fd, 65536)
        except OSError:  # the terminal closed: the program ended
            return False
        if not chunk:
            return False
        seen.extend(chunk)
    return True


def _clone(tmp: Path) -> Path:
    clone = tmp / "clone"
    head = subprocess.run(
        ["git", "-C", str(ROOT), "rev-parse", "HEAD"], capture_output=True, text=True, check=True
    ).stdout.strip()
    subprocess.run(["git", "clone", "--quiet", str(ROOT), str(clone)], check=True)
    subprocess.run(["git", "-C", str(clone), "checkout", "--quiet", head], check=True)
    return clone


def test_make_run_in_a_fresh_clone_shows_progress_and_ctrl_c_exits_0(tmp_path: Path) -> None:
    clone = _clone(tmp_path)
    data_home = tmp_path / "data"
    data_home.mkdir()
    env = {k: v for k, v in os.environ.items() if not k.startswith(("DMS_", "MAKE"))}
    env |= {
        "XDG_DATA_HOME": str(data_home),
        "DMS_ZENOH__LISTEN": f'["tcp/127.0.0.1:{free_port()}"]',  # not the default port
        "TERM": "dumb",
    }
    pid, fd = pty.fork()
    if pid == 0:  # the child: make in the terminal
        os.chdir(clone)
        os.execvpe("make", ["make", "run"], env)
    seen = bytearray()
    try:
        started = _read_until(fd, DECISION, seen, INSTALL_TIMEOUT_S)
        text = seen.decode(errors="replace")
        assert started, text[-3000:]
        before = text[: DECISION.search(seen).start()]  # type: ignore[union-attr]
        assert "make: installing dms" in before, before[-3000:]
        assert "Successfully installed" in before, before[-3000:]  # pip said what it did
        os.write(fd, CTRL_C)
        _read_until(fd, re.compile(rb"(?!x)x"), seen, 60.0)  # to the end of its output
    finally:
        _, status = os.waitpid(pid, 0)
        os.close(fd)
    text = seen.decode(errors="replace")
    assert os.waitstatus_to_exitcode(status) == 0, text[-3000:]
    assert "Error" not in text[text.index("^C") if "^C" in text else 0 :], text[-3000:]
    assert (clone / ".venv" / "demo.db").is_file()
    assert list(data_home.iterdir()) == [], "the default database folder stays untouched"
