"""The README's zenoh-python client, run as written against a real daemon."""

from __future__ import annotations

import json
import re
import subprocess
import sys
import threading
from pathlib import Path
from typing import Any

import pytest

from tests.integration.harness import running_daemon

pytestmark = pytest.mark.integration

README = Path(__file__).resolve().parents[2] / "README.md"


def readme_client() -> str:
    text = README.read_text()
    found = re.search(r"```python\n(import json, zenoh\n.*?)```", text, re.S)
    assert found, "README has no zenoh client"
    return found.group(1)


def _decision_in(line: str) -> dict[str, Any] | None:
    """The decision printed on ``line``: the client prints from two threads, so a decision
    may share its line with another print."""
    start = line.find('{"tick"')
    if start < 0:
        return None
    decision, _ = json.JSONDecoder().raw_decode(line[start:])
    return decision if isinstance(decision, dict) else None


def test_the_readme_client_starts_jokes_and_sees_the_decision(tmp_path: Path) -> None:
    code = readme_client()
    assert len(code.strip().splitlines()) <= 10
    with running_daemon(tmp_path) as (daemon, _session):
        script = tmp_path / "client.py"
        script.write_text(code.replace("tcp/127.0.0.1:7447", f"tcp/127.0.0.1:{daemon.port}"))
        client = subprocess.Popen(
            [sys.executable, str(script)],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
        )
        assert client.stdout is not None and client.stdin is not None
        watchdog = threading.Timer(30.0, client.kill)  # a deadline, not a pause
        watchdog.start()
        lines: list[str] = []
        try:
            for line in client.stdout:
                lines.append(line)
                decision = _decision_in(line)
                if decision is not None and (decision["action"], decision["activity"]) == (
                    "start",
                    "jokes",
                ):
                    assert decision["reason"] == "user_request"
                    break
            else:
                raise AssertionError("no jokes decision from the client:\n" + "".join(lines))
            client.stdin.write("\n")
            client.stdin.flush()
            lines.extend(client.stdout.readlines())  # up to the client's exit
            assert client.wait(20) == 0, "".join(lines)
        finally:
            watchdog.cancel()
            client.kill()
        assert any("now running:" in line for line in lines)
