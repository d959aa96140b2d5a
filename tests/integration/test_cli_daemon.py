"""``dms run`` as an operator runs it: log flags, environment variables, reloads, missed
ticks and systemd's notify protocol, each against a real daemon process over Zenoh on
127.0.0.1 and a real SQLite file.

Every wait is for a message, a log line, a datagram or a liveliness token, with a
deadline; the only timed pause is the one that makes the loop miss ticks (SIGSTOP).
"""

from __future__ import annotations

import itertools
import json
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest
import zenoh

from tests.integration.harness import (
    READY_TIMEOUT_S,
    Collector,
    StderrLines,
    client_session,
    free_port,
    wait_token,
)

pytestmark = pytest.mark.integration

_SCRIPT = Path(sys.executable).with_name("dms")
DMS = [str(_SCRIPT)] if _SCRIPT.exists() else [sys.executable, "-m", "dms.cli"]

CONFIG = (
    'robot_id = "fromtoml"\nseed = 3\nlog_format = "text"\n'
    '[inputs]\nstale_after_s = { "perception/user" = 30.0 }\n'
    "[controller]\nsession_questions = 0\nquestion_every = 0\nfeedback_probability = 0.0\n"
)


class Daemon:
    """``dms run`` with a given environment, its stderr read line by line."""

    def __init__(self, tmp: Path, port: int, args: tuple[str, ...], env: dict[str, str]) -> None:
        self.port = port
        config = tmp / "dms.toml"
        config.write_text(CONFIG)
        clean = {k: v for k, v in os.environ.items() if not k.startswith(("DMS_", "NOTIFY_"))}
        self.proc = subprocess.Popen(
            [
                *DMS,
                "run",
                "--config",
                str(config),
                "--db",
                str(tmp / "dms.db"),
                "--quiet",
                "--listen",
                f"tcp/127.0.0.1:{port}",
                *args,
            ],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
            env={**clean, "PYTHONUNBUFFERED": "1", **env},
        )
        self.stderr = StderrLines(self.proc)

    def lines(self) -> list[str]:
        return self.stderr.text().splitlines()

    def wait_line(
        self, predicate: Callable[[str], bool], timeout: float = 30.0, start: int = 0
    ) -> str:
        """The first stderr line from index ``start`` on that satisfies ``predicate``."""
        return self.stderr.wait_for(predicate, timeout, start)

    def stop(self) -> int:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
        try:
            return self.proc.wait(30)
        finally:
            self.stderr.text()  # every line read

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(10)


@contextmanager
def daemon(
    tmp: Path, robot: str, *args: str, env: dict[str, str] | None = None
) -> Iterator[tuple[Daemon, zenoh.Session]]:
    process = _started(tmp, args, env or {})
    session = client_session(process.port)
    try:
        wait_token(session, f"robots/{robot}/alive/dms")
        yield process, session
    finally:
        process.kill()
        session.close()


def _started(tmp: Path, args: tuple[str, ...], env: dict[str, str]) -> Daemon:
    return Daemon(tmp, free_port(), args, env)


def test_environment_over_toml_and_flags_over_environment(tmp_path: Path) -> None:
    env = {"DMS_ROBOT_ID": "fromenv", "DMS_LOG_FORMAT": "text", "DMS_LOG_LEVEL": "info"}
    with daemon(tmp_path, "fromenv", "--log-format", "json", env=env) as (process, session):
        # robot_id: the environment over the TOML; log_format: the flag over both.
        ready = json.loads(process.wait_line(lambda line: '"event": "ready"' in line))
        assert ready["robot_id"] == "fromenv" and ready["level"] == "info"
        assert ready["logger"] == "dms.daemon" and "alive/dms declared" in ready["message"]
        assert not _token_now(session, "robots/fromtoml/alive/dms")
        assert process.stop() == 0
    for line in process.lines():
        json.loads(line)  # every line of the log is a JSON object


def test_a_bad_environment_variable_is_one_line(tmp_path: Path) -> None:
    (tmp_path / "dms.toml").write_text(CONFIG)
    clean = {k: v for k, v in os.environ.items() if not k.startswith("DMS_")}
    for name, value in (
        ("DMS_CONTROLLER__TICK_PERIOD_S", "fast"),
        ("DMS_ROBOT", "nao"),
        ("DMS_ZENOH__CONNECT", "[not json"),
    ):
        result = subprocess.run(
            [*DMS, "run", "--config", str(tmp_path / "dms.toml"), "--db", str(tmp_path / "x.db")],
            capture_output=True,
            text=True,
            timeout=120,
            env={**clean, name: value},
        )
        assert result.returncode == 1, result.stderr
        line = result.stderr.strip()
        assert "\n" not in line and line.startswith("dms: ") and name.split("__")[0] in line, line


def test_a_reload_and_missed_ticks_are_logged(tmp_path: Path) -> None:
    with daemon(tmp_path, "fromtoml", "--log-level", "info") as (process, session):
        process.wait_line(lambda line: "ready on" in line)
        states = Collector(session, "robots/fromtoml/dms/state")
        process.proc.send_signal(signal.SIGHUP)
        reloaded = process.wait_line(lambda line: "rules and behaviors reloaded" in line)
        assert " INFO dms.reloader: " in reloaded and "robot_id=fromtoml" in reloaded
        states.wait_count(1, READY_TIMEOUT_S)  # the loop runs (its store opened after ready)
        # Freeze the process for three periods: the loop then finds itself behind.
        before = len(process.lines())
        process.proc.send_signal(signal.SIGSTOP)
        try:
            time.sleep(1.6)  # ok-sleep: the frozen process misses ticks for this long
        finally:
            process.proc.send_signal(signal.SIGCONT)
        missed = process.wait_line(lambda line: "event=missed_ticks" in line, start=before)
        assert " WARNING dms.daemon: missed " in missed
        fields = dict(part.split("=", 1) for part in missed.split() if "=" in part)
        assert int(fields["missed"]) >= 2 and int(fields["missed_total"]) >= int(fields["missed"])
        assert process.stop() == 0


def test_warning_level_hides_the_info_lines(tmp_path: Path) -> None:
    with daemon(tmp_path, "fromtoml", "--log-level", "warning") as (process, _session):
        process.proc.send_signal(signal.SIGHUP)
        assert process.stop() == 0
    assert not [line for line in process.lines() if " INFO " in line]


# ------------------------------------------------------------------ systemd notify


class NotifySocket:
    """A unix datagram socket the test listens on, as systemd's ``$NOTIFY_SOCKET``."""

    def __init__(self) -> None:
        # A short folder: a unix socket's path must fit in 108 bytes.
        self.folder = tempfile.mkdtemp(prefix="dms-notify-", dir="/tmp")
        self.path = os.path.join(self.folder, "notify")
        self.sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        self.sock.bind(self.path)
        self.received: list[tuple[float, dict[str, str]]] = []

    def next(self, timeout: float) -> dict[str, str]:
        self.sock.settimeout(timeout)
        data = self.sock.recv(4096)
        states = dict(line.split("=", 1) for line in data.decode().splitlines())
        self.received.append((time.monotonic(), states))
        return states

    def wait_for(self, name: str, timeout: float) -> dict[str, str]:
        deadline = time.monotonic() + timeout
        while True:
            left = deadline - time.monotonic()
            assert left > 0, f"no {name} within {timeout}s: {self.received}"
            states = self.next(left)
            if name in states:
                return states

    def close(self) -> None:
        self.sock.close()
        os.unlink(self.path)
        os.rmdir(self.folder)


def _token_now(session: zenoh.Session, key: str) -> bool:
    """Whether ``key`` is declared, asked of the daemon itself (a liveliness query)."""
    replies = session.liveliness().get(key, timeout=10.0)
    return any(reply.ok is not None for reply in replies)


def test_systemd_ready_after_alive_and_watchdog_from_the_tick_loop(tmp_path: Path) -> None:
    notify = NotifySocket()
    # The test's session listens and the daemon connects to it, so that the link is up
    # before the daemon declares alive/dms: at READY the daemon must answer for it.
    listen_port = free_port()
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("listen/endpoints", json.dumps([f"tcp/127.0.0.1:{listen_port}"]))
    conf.insert_json5("scouting/multicast/enabled", "false")
    session = zenoh.open(conf)
    process = _started(
        tmp_path,
        ("--connect", f"tcp/127.0.0.1:{listen_port}"),
        {"NOTIFY_SOCKET": notify.path, "WATCHDOG_USEC": "2000000"},
    )
    try:
        ready = notify.wait_for("READY", READY_TIMEOUT_S)
        # The order (alive/dms declared, then READY) is checked on an in-memory bus in
        # tests/core/test_cli_notify.py; here, over a real link, the token must be there
        # for another process right after READY. It reaches the test's session when
        # the link comes up, which on a loaded machine may be just after READY, so
        # this waits for it (a liveliness subscriber with history) instead of asking
        # once: a single query could race the link (it failed so, once, under load).
        wait_token(session, "robots/fromtoml/alive/dms", timeout=10.0)
        assert ready["READY"] == "1" and ready["MAINPID"] == str(process.proc.pid)
        assert "fromtoml" in ready.get("STATUS", "")
        # The watchdog keeps coming from the tick loop, well within its 2 s period.
        watchdogs = [notify.wait_for("WATCHDOG", 10.0) for _ in range(5)]
        assert all(states == {"WATCHDOG": "1"} for states in watchdogs)
        times = [t for t, states in notify.received if "WATCHDOG" in states]
        gaps = [b - a for a, b in itertools.pairwise(times)]
        assert max(gaps) < 2.0, gaps
        assert process.stop() == 0
        assert notify.wait_for("STOPPING", 10.0) == {"STOPPING": "1"}
    finally:
        process.kill()
        session.close()
        notify.close()


def test_no_notify_socket_no_notification(tmp_path: Path) -> None:
    """Outside systemd the daemon runs as before (the other tests run it so too)."""
    from dms.notify import Notifier

    quiet = Notifier(env={})
    assert not quiet.enabled and not quiet.ready() and not quiet.watchdog()
    other: dict[str, Any] = {"NOTIFY_SOCKET": "@x", "WATCHDOG_USEC": "1000000"}
    assert Notifier(env={**other, "WATCHDOG_PID": "1"}).watchdog_every_s is None
    assert Notifier(env=other).watchdog_every_s == 0.25
