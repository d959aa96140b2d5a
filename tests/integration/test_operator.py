"""The operator's commands (``dms topics``, ``dms echo``, ``dms state``) as real processes
against a real daemon over Zenoh on 127.0.0.1, and the refusal of a second daemon for a
robot id already alive.

Every wait is for a message, a line or a token, with a deadline.
"""

from __future__ import annotations

import json
import os
import queue
import signal
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import zenoh

from dms.bus import ZenohBus, make_config
from dms.kernel.errors import ConfigError
from tests.integration.harness import (
    READY_TIMEOUT_S,
    Collector,
    DaemonProcess,
    client_session,
    free_port,
    put,
)

pytestmark = pytest.mark.integration

DMS = [sys.executable, "-m", "dms.cli"]
ENV = dict(os.environ, PYTHONUNBUFFERED="1")


@pytest.fixture(scope="module")
def daemon(
    tmp_path_factory: pytest.TempPathFactory,
) -> Iterator[tuple[DaemonProcess, zenoh.Session]]:
    """One daemon for the module's tests (each start costs seconds on a loaded machine)."""
    tmp = tmp_path_factory.mktemp("operator")
    process = DaemonProcess(tmp)
    session = client_session(process.port)
    try:
        process.start(session)
        yield process, session
    finally:
        process.kill()
        session.close()


def _run(*args: str, timeout: float = 60.0) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*DMS, *args], capture_output=True, text=True, timeout=timeout, env=ENV)


def _connect(daemon: DaemonProcess) -> list[str]:
    return ["--connect", f"tcp/127.0.0.1:{daemon.port}"]


def _one_line_refusal(
    done: subprocess.CompletedProcess[str], expected: str, after: str | None = None
) -> None:
    """Exit 1 and one ``dms: ...`` line on stderr (after the line ``after`` began with)."""
    assert done.returncode == 1, done
    lines = done.stderr.strip().splitlines()
    if after is not None:
        assert lines[0].startswith(after), done.stderr
        lines = lines[1:]
    assert len(lines) == 1 and lines[0].startswith("dms: ") and expected in lines[0], done.stderr


class Streaming:
    """A command whose stdout and stderr lines are read as they come."""

    def __init__(self, *args: str) -> None:
        self.proc = subprocess.Popen(
            [*DMS, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ENV
        )
        self.out: queue.Queue[str | None] = queue.Queue()
        self.err: queue.Queue[str | None] = queue.Queue()
        for stream, lines in ((self.proc.stdout, self.out), (self.proc.stderr, self.err)):
            threading.Thread(target=self._drain, args=(stream, lines), daemon=True).start()

    @staticmethod
    def _drain(stream: Any, lines: queue.Queue[str | None]) -> None:
        for line in stream:
            lines.put(line)
        lines.put(None)

    def line(self, lines: queue.Queue[str | None], timeout: float = READY_TIMEOUT_S) -> str:
        try:
            line = lines.get(timeout=timeout)
        except queue.Empty:
            raise AssertionError(f"no line within {timeout}s") from None
        assert line is not None, "the command ended"
        return line

    def stop(self) -> int:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
        try:
            return self.proc.wait(20)
        finally:
            if self.proc.poll() is None:
                self.proc.kill()


def test_state_prints_the_daemons_state(daemon: tuple[DaemonProcess, zenoh.Session]) -> None:
    process, session = daemon
    states = Collector(session, "robots/mini/dms/state")
    running = states.wait_for(lambda s: s["activity"] is not None)["activity"]["name"]

    pretty = _run("state", *_connect(process))
    assert pretty.returncode == 0, pretty.stderr
    lines = pretty.stdout.splitlines()
    assert lines[0].startswith("robot      mini  tick ")
    assert any(line.startswith(f"activity   {running} (") for line in lines), pretty.stdout
    assert any(line.strip().startswith("rest ") for line in lines), "the drives' table"
    assert lines[-1].startswith("inputs     perception/user ")

    raw = _run("state", "--json", *_connect(process))
    state = json.loads(raw.stdout)
    assert state["robot"] == "mini" and isinstance(state["tick"], int)
    assert set(state["motivation"]["drives"]) >= {"rest", "social", "play"}


def test_echo_prints_each_message_until_count_or_ctrl_c(
    daemon: tuple[DaemonProcess, zenoh.Session],
) -> None:
    process, session = daemon
    two = _run("echo", "dms/state", "--json", "--count", "2", *_connect(process))
    assert two.returncode == 0, two.stderr
    lines = [json.loads(line) for line in two.stdout.splitlines()]
    assert [line["key"] for line in lines] == ["robots/mini/dms/state"] * 2
    assert lines[0]["payload"]["tick"] < lines[1]["payload"]["tick"]
    assert lines[0]["time"].endswith("Z")

    # A wildcard key, text output: the header line, then indented JSON.
    text = _run("echo", "robots/mini/dms/*", "--count", "1", *_connect(process))
    assert text.returncode == 0, text.stderr
    header, *body = text.stdout.splitlines()
    assert header.startswith("--- robots/mini/dms/")
    assert json.loads("\n".join(body))

    # A decision as it happens; Ctrl-C ends the command with exit 0.
    echo = Streaming("echo", "dms/decision", *_connect(process))
    try:
        assert echo.line(echo.err).startswith("dms: echoing robots/mini/dms/decision")
        # Its subscription reaches the daemon a moment after it says so (Zenoh declares
        # asynchronously): a request sent before that is decided unseen, so it is sent
        # again, alternating with a cancel, until the echo prints a decision.
        printed: list[str] = []
        for attempt in range(10):
            action = "start" if attempt % 2 == 0 else "cancel"
            put(session, "request", {"action": action, "activity": "jokes", "by": "test"})
            try:
                printed.append(echo.line(echo.out, timeout=3.0))
                break
            except AssertionError:
                continue
        assert printed, "no decision echoed"
        while not any('"activity": "jokes"' in line for line in printed):
            printed.append(echo.line(echo.out))
        assert printed[0].startswith("--- robots/mini/dms/decision ")
    finally:
        code = echo.stop()
    assert code == 0


def test_topics_lists_keys_and_tokens(daemon: tuple[DaemonProcess, zenoh.Session]) -> None:
    process, _session = daemon
    # An input module listening on its own port: the daemon is a peer and does not pass
    # one peer's token on to another, so the tool connects to both (--connect twice).
    module_port = free_port()
    module = zenoh.open(_listening(module_port))
    token = module.liveliness().declare_token("robots/mini/alive/perception/user")
    try:
        both = [*_connect(process), "--connect", f"tcp/127.0.0.1:{module_port}"]
        done = _run("topics", "--json", "--duration", "1.5", *both)
    finally:
        token.undeclare()
        module.close()
    assert done.returncode == 0, done.stderr
    found = json.loads(done.stdout)
    assert found["robot"] == "mini"
    assert found["keys"]["dms/state"]["messages"] >= 1
    assert found["tokens"] == ["alive/dms", "alive/perception/user"]

    text = _run("topics", "--duration", "1", *_connect(process))
    assert text.returncode == 0, text.stderr
    assert "  dms/state " in text.stdout and "  alive/dms" in text.stdout


def _listening(port: int) -> zenoh.Config:
    config = zenoh.Config()
    config.insert_json5("mode", '"peer"')
    config.insert_json5("listen/endpoints", json.dumps([f"tcp/127.0.0.1:{port}"]))
    config.insert_json5("scouting/multicast/enabled", "false")
    return config


def test_the_tools_take_a_zenoh_file(
    daemon: tuple[DaemonProcess, zenoh.Session], tmp_path: Path
) -> None:
    """``--zenoh-config FILE`` instead of ``--connect``: the file's endpoints stand."""
    process, _session = daemon
    zenoh_file = tmp_path / "tool.json5"
    zenoh_file.write_text(
        json.dumps(
            {
                "mode": "peer",
                "connect": {"endpoints": [f"tcp/127.0.0.1:{process.port}"]},
                "listen": {"endpoints": []},
                "scouting": {"multicast": {"enabled": False}},
            }
        )
    )
    use = ["--zenoh-config", str(zenoh_file)]
    state = _run("state", "--json", *use)
    assert state.returncode == 0 and json.loads(state.stdout)["robot"] == "mini", state.stderr
    echo = _run("echo", "dms/state", "--json", "--count", "1", *use)
    assert echo.returncode == 0 and json.loads(echo.stdout)["key"] == "robots/mini/dms/state"
    topics = _run("topics", "--json", "--duration", "1", *use)
    assert topics.returncode == 0 and "alive/dms" in json.loads(topics.stdout)["tokens"]


def test_bad_input_is_one_line_and_nonzero(daemon: tuple[DaemonProcess, zenoh.Session]) -> None:
    process, _session = daemon
    other = ["--robot-id", "nobody", *_connect(process)]
    _one_line_refusal(_run("state", "--timeout", "1", *other), "no reply from robots/nobody/")
    quiet = _run("echo", "dms/state", "--timeout", "0.5", *other)
    _one_line_refusal(quiet, "no message on", after="dms: echoing robots/nobody/dms/state")
    _one_line_refusal(_run("topics", "--duration", "0.5", *other), "nothing under robots/nobody/")
    _one_line_refusal(_run("echo", "dms//state", *_connect(process)), "bad key expression")
    _one_line_refusal(_run("state", "--robot-id", "Mini!"), "--robot: 'Mini!'")
    nowhere = ["--connect", f"tcp/127.0.0.1:{free_port()}"]
    _one_line_refusal(_run("state", *nowhere), "cannot open the Zenoh session")


def test_a_second_daemon_for_a_live_robot_refuses_to_start(
    daemon: tuple[DaemonProcess, zenoh.Session], tmp_path: Path
) -> None:
    process, session = daemon
    decisions = Collector(session, "robots/mini/dms/decision")
    states = Collector(session, "robots/mini/dms/state")
    states.wait_count(1)
    done = subprocess.run(
        [
            *DMS,
            "run",
            "--config",
            str(process.config),
            "--db",
            f"sqlite:///{tmp_path / 'second.db'}",
            "--listen",
            f"tcp/127.0.0.1:{free_port()}",
            *_connect(process),
        ],
        capture_output=True,
        text=True,
        timeout=120,
        env=ENV,
    )
    assert done.returncode == 1, done
    refusal = "dms: robot mini is already running: robots/mini/alive/dms is declared on the bus"
    assert refusal in done.stderr and "Traceback" not in done.stderr, done.stderr
    # The refused daemon published nothing on the live robot's keys (no shutdown).
    mark = states.mark()
    states.wait_for(lambda s: True, start=mark)  # the live daemon ticks on
    assert all(d["reason"] != "shutdown" for d in decisions.messages)
    assert all(s["tick"] > 0 for s in states.messages)
    assert process.proc is not None and process.proc.poll() is None


def test_the_refusal_is_per_robot_id() -> None:
    """On one bus, ``alive/dms`` of robot ``a`` refuses another ``a``, not a ``b``."""
    port = free_port()
    first = ZenohBus("a", make_config([f"tcp/127.0.0.1:{port}"]))
    first.start({})
    first.declare_alive()
    peers = [f"tcp/127.0.0.1:{port}"]
    try:
        again = ZenohBus("a", make_config([f"tcp/127.0.0.1:{free_port()}"], peers))
        with pytest.raises(ConfigError, match="robot a is already running"):
            again.start({})
        again.close()
        other = ZenohBus("b", make_config([f"tcp/127.0.0.1:{free_port()}"], peers))
        other.start({})
        other.close()
    finally:
        first.close()
