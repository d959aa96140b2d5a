"""The operator's habits, typed at a shell: each test runs ``dms`` as a subprocess, as a
person (or a ROS user used to ``ros2 topic echo``, ``ros2 bag record|play``) would.

``dms request``, keys with a leading ``/``, ``dms record`` naming its file and playing
one back, a ``foxglove.websocket.v1``-only client, and the errors a person can act on.
Every wait is for a message, a line or a process's exit, with a deadline.
"""

from __future__ import annotations

import asyncio
import itertools
import json
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import websockets
import zenoh

from sim.recording import McapRecorder
from tests.integration.harness import (
    READY_TIMEOUT_S,
    DaemonProcess,
    StderrLines,
    client_session,
    free_port,
    put,
    wait_subscribed,
)
from tests.integration.test_foxglove import Bridge

pytestmark = pytest.mark.integration

DMS = [sys.executable, "-m", "dms.cli"]
ENV = {k: v for k, v in os.environ.items() if not k.startswith("DMS_")} | {"PYTHONUNBUFFERED": "1"}


def dms(
    *args: str, cwd: Path | None = None, timeout: float = 60.0
) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [*DMS, *args], capture_output=True, text=True, timeout=timeout, env=ENV, cwd=cwd
    )


@pytest.fixture(scope="module")
def daemon(
    tmp_path_factory: pytest.TempPathFactory,
) -> Iterator[tuple[DaemonProcess, zenoh.Session]]:
    """One daemon for the tests that need one (each start costs seconds)."""
    process = DaemonProcess(tmp_path_factory.mktemp("shell"))
    session = client_session(process.port)
    try:
        process.start(session)
        yield process, session
    finally:
        process.kill()
        session.close()


def _connect(process: DaemonProcess) -> list[str]:
    return ["--connect", f"tcp/127.0.0.1:{process.port}"]


# ---------------------------------------------------------------------- dms request


def test_request_start_prints_the_start_decision_and_cancel_its_cancel(
    daemon: tuple[DaemonProcess, zenoh.Session],
) -> None:
    process, _ = daemon
    started = dms("request", "start", "jokes", *_connect(process))
    assert started.returncode == 0, started.stderr
    last = started.stdout.strip().splitlines()[-1]
    assert " start    jokes [user_request by user] (requested by cli)" in last, started.stdout
    as_json = dms("request", "pause", "--json", "--by", "nurse", *_connect(process))
    assert as_json.returncode == 0, as_json.stderr
    decision = json.loads(as_json.stdout.strip().splitlines()[-1])
    assert (decision["action"], decision["activity"]) == ("pause", "jokes")
    assert decision["detail"] == "requested by nurse"
    cancelled = dms("request", "cancel", *_connect(process))
    assert cancelled.returncode == 0, cancelled.stderr
    assert " cancel   jokes [user_request" in cancelled.stdout, cancelled.stdout


def test_request_mistakes_are_said_before_anything_is_sent() -> None:
    typo = dms("request", "start", "jokez", "--connect", "tcp/127.0.0.1:1")
    assert typo.returncode == 1
    assert typo.stderr.strip() == "dms: unknown activity 'jokez'; did you mean jokes?"
    bare = dms("request", "start", "--connect", "tcp/127.0.0.1:1")
    assert bare.returncode == 1 and "start needs an activity" in bare.stderr


def test_request_without_a_daemon_exits_1_within_its_timeout() -> None:
    started = time.monotonic()
    done = dms(
        "request", "start", "jokes", "--connect", f"tcp/127.0.0.1:{free_port()}", "--timeout", "2"
    )
    took = time.monotonic() - started
    assert done.returncode == 1, done
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("dms: "), done.stderr
    assert took < 2 + 8, f"{took:.1f} s (2 s of timeout, the rest the interpreter's start)"


# ---------------------------------------------------------------------- keys


@pytest.mark.parametrize(
    "key", ["/robots/mini/dms/state", "robots/mini/dms/state", "dms/state", "/dms/state"]
)
def test_echo_takes_a_key_with_or_without_slash_absolute_or_relative(
    daemon: tuple[DaemonProcess, zenoh.Session], key: str
) -> None:
    process, _ = daemon
    done = dms("echo", key, "--json", "--count", "1", "--timeout", "10", *_connect(process))
    assert done.returncode == 0, done.stderr
    line = json.loads(done.stdout)
    assert line["key"] == "robots/mini/dms/state" and line["payload"]["robot"] == "mini"


def test_echo_of_a_mistyped_key_says_nobody_publishes_it_and_names_the_nearest(
    daemon: tuple[DaemonProcess, zenoh.Session],
) -> None:
    process, _ = daemon
    typo = dms("echo", "dms/decison", "--timeout", "6", *_connect(process))
    assert typo.returncode == 1
    assert (
        "dms: nothing on robots/mini/dms/decison after 3 s, and it is no key the daemon uses: "
        "did you mean dms/decision?"
    ) in typo.stderr.splitlines(), typo.stderr
    quiet = dms("echo", "robot/feedback", "--timeout", "4", *_connect(process))  # known, quiet
    assert quiet.returncode == 1 and "did you mean" not in quiet.stderr, quiet.stderr


def test_topics_takes_a_key_too(daemon: tuple[DaemonProcess, zenoh.Session]) -> None:
    process, _ = daemon
    done = dms("topics", "/dms/*", "--json", "--duration", "1.5", *_connect(process))
    assert done.returncode == 0, done.stderr
    assert list(json.loads(done.stdout)["keys"]) == ["dms/state"]


# ---------------------------------------------------------------------- dms record


def test_record_without_out_names_its_file_in_the_current_folder(
    daemon: tuple[DaemonProcess, zenoh.Session], tmp_path: Path
) -> None:
    process, _ = daemon
    done = dms("record", "--duration", "1.5", *_connect(process), cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    files = list(tmp_path.glob("dms_mini_*.mcap"))
    assert len(files) == 1, list(tmp_path.iterdir())
    name = files[0].name
    assert len(name) == len("dms_mini_20261127-101500.mcap"), name
    assert f"into {name}" in done.stderr
    info = dms("record", "info", name, "--json", cwd=tmp_path)
    assert info.returncode == 0 and json.loads(info.stdout)["messages"] > 0


def _listening_peer(port: int) -> zenoh.Session:
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("listen/endpoints", json.dumps([f"tcp/127.0.0.1:{port}"]))
    conf.insert_json5("scouting/multicast/enabled", "false")
    return zenoh.open(conf)


@pytest.mark.parametrize("rate", [1.0, 2.0])
def test_record_play_republishes_at_the_recorded_pace(tmp_path: Path, rate: float) -> None:
    recording = tmp_path / "probe.mcap"
    recorder = McapRecorder(recording, "playback")
    start_ns = 1_700_000_000_000_000_000
    for index in range(5):
        payload = json.dumps({"index": index}).encode()
        recorder.write("robots/playback/test/probe", payload, start_ns + index * 400_000_000)
    recorder.close()
    port = free_port()
    seen: list[tuple[float, str, dict[str, Any]]] = []
    lock = threading.Lock()

    def on_sample(sample: zenoh.Sample) -> None:
        with lock:
            seen.append(
                (time.monotonic(), str(sample.key_expr), json.loads(sample.payload.to_bytes()))
            )

    session = _listening_peer(port)
    try:
        session.declare_subscriber("robots/playback/**", on_sample)
        done = dms(
            "record",
            "play",
            str(recording),
            "--rate",
            str(rate),
            "--connect",
            f"tcp/127.0.0.1:{port}",
        )
    finally:
        session.close()
    assert done.returncode == 0, done.stderr
    assert "5 messages played" in done.stderr
    assert [payload["index"] for _, _, payload in seen] == [0, 1, 2, 3, 4]
    assert {key for _, key, _ in seen} == {"robots/playback/test/probe"}
    gaps = [later[0] - earlier[0] for earlier, later in itertools.pairwise(seen)]
    expected = 0.4 / rate
    assert all(abs(gap - expected) < 0.15 for gap in gaps), (expected, gaps)
    total = seen[-1][0] - seen[0][0]
    assert abs(total - 4 * expected) < 0.15, (4 * expected, total)  # deadlines: no drift


# ---------------------------------------------------------------------- dms foxglove


async def _handshake(port: int, subprotocols: list[str]) -> tuple[str | None, dict[str, Any]]:
    async with websockets.connect(
        f"ws://127.0.0.1:{port}",
        subprotocols=subprotocols,
    ) as ws:
        first = json.loads(await asyncio.wait_for(ws.recv(), 20.0))
        return ws.subprotocol, first


def test_foxglove_serves_a_foxglove_websocket_v1_only_client(
    daemon: tuple[DaemonProcess, zenoh.Session],
) -> None:
    process, _ = daemon
    bridge = Bridge(process.port, "--robot", "mini")
    try:
        bridge.wait_ready()
        legacy, hello = asyncio.run(_handshake(bridge.port, ["foxglove.websocket.v1"]))
        assert legacy == "foxglove.websocket.v1"
        assert hello["op"] == "serverInfo", hello
        current, hello = asyncio.run(_handshake(bridge.port, ["foxglove.sdk.v1"]))
        assert current == "foxglove.sdk.v1" and hello["op"] == "serverInfo"
    finally:
        assert bridge.stop() == 0


def test_foxglove_keeps_robot_id_as_a_hidden_alias() -> None:
    help_text = dms("foxglove", "--help").stdout
    assert "--robot " in help_text and "--robot-id" not in help_text
    bad = dms("foxglove", "--robot-id", "Bad Id", "--port", "0")
    assert bad.returncode == 1 and "--robot 'Bad Id'" in bad.stderr


# ---------------------------------------------------------------------- errors


def test_an_endpoint_without_its_protocol_is_one_line_naming_the_form(tmp_path: Path) -> None:
    done = dms("run", "--listen", "127.0.0.1:18508", "--db", str(tmp_path / "x.db"))
    assert done.returncode == 1
    assert done.stderr.strip() == "dms: `127.0.0.1:18508`: an endpoint is `tcp/HOST:PORT`"
    assert not (tmp_path / "x.db").exists()
    tool = dms("echo", "dms/state", "--connect", "localhost:7447")
    assert tool.stderr.strip() == "dms: `localhost:7447`: an endpoint is `tcp/HOST:PORT`"


def test_every_wrong_config_field_is_named_with_its_likely_name(tmp_path: Path) -> None:
    config = tmp_path / "dms.toml"
    config.write_text('robot_idd = "x"\n[controller]\ntick_perod_s = 1\n')
    done = dms("run", "--config", str(config))
    assert done.returncode == 1
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr
    assert "robot_idd: Extra inputs are not permitted (did you mean robot_id?)" in lines[0]
    assert (
        "controller.tick_perod_s: Extra inputs are not permitted (did you mean tick_period_s?)"
        in lines[0]
    )
    assert "more)" not in lines[0]


def test_an_unknown_visitor_is_refused_before_ready(tmp_path: Path) -> None:
    port = free_port()
    done = dms(
        "run",
        "--visitor",
        "bob",
        "--db",
        str(tmp_path / "x.db"),
        "--listen",
        f"tcp/127.0.0.1:{port}",
    )
    assert done.returncode == 1
    assert "ready" not in done.stderr and "ready" not in done.stdout
    assert done.stderr.strip().splitlines()[-1].startswith("dms: unknown persona 'bob' (shipped: ")


class Daemon:
    """``dms run`` with chosen flags; its stderr read line by line."""

    def __init__(self, tmp: Path, *flags: str) -> None:
        self.port = free_port()
        self.proc = subprocess.Popen(
            [
                *DMS,
                "run",
                "--db",
                str(tmp / "dms.db"),
                "--listen",
                f"tcp/127.0.0.1:{self.port}",
                "--seed",
                "2",
                *flags,
            ],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env=ENV,
        )
        self.stderr = StderrLines(self.proc)
        assert self.proc.stdout is not None
        threading.Thread(target=self.proc.stdout.read, daemon=True).start()

    def stop(self) -> list[str]:
        """SIGTERM; every stderr line once it has exited (0)."""
        self.proc.send_signal(signal.SIGTERM)
        assert self.proc.wait(30) == 0, self.stderr.text()
        return self.stderr.text().splitlines()

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(10)


def test_log_level_debug_shows_the_daemons_decisions_not_alembics(tmp_path: Path) -> None:
    daemon = Daemon(tmp_path, "--log-level", "debug", "--quiet")
    session = client_session(daemon.port)
    try:
        daemon.stderr.wait_for(" ready on ")
        # the daemon's subscriber seen from this session, or the touch could go nowhere
        wait_subscribed(session, "robots/mini/perception/touch")
        put(session, "perception/touch", {"part": "head", "kind": "tap"})
        daemon.stderr.wait_for("perception/touch accepted")
        lines = daemon.stop()
    finally:
        daemon.kill()
        session.close()
    debug = [line for line in lines if " DEBUG dms." in line]
    assert any("storage: profiles and agenda in sqlite:///" in line for line in debug), lines
    assert any("bus: subscribed to" in line for line in debug), lines
    assert not [line for line in lines if "alembic" in line.lower()], lines


def test_log_format_json_makes_every_line_json_the_visitors_too(tmp_path: Path) -> None:
    daemon = Daemon(tmp_path, "--log-format", "json", "--visitor", "demo")
    try:
        daemon.stderr.wait_for('"logger": "sim.visitor"', timeout=READY_TIMEOUT_S + 20)
        lines = daemon.stop()
    finally:
        daemon.kill()
    assert lines
    parsed = [json.loads(line) for line in lines]  # raises on any line that is not JSON
    assert any(item["logger"] == "sim.visitor" and item["event"] == "visitor" for item in parsed)


def test_a_command_needing_the_simulators_extras_says_how_to_get_them() -> None:
    hide = "import sys; sys.modules['scipy'] = None; from dms.cli import main; "
    study = subprocess.run(
        [sys.executable, "-c", hide + "sys.exit(main(['sim', 'study', '--sessions', '1']))"],
        capture_output=True,
        text=True,
        timeout=60,
        env=ENV,
    )
    assert study.returncode == 1
    assert study.stderr.strip() == (
        "dms: dms sim study needs the simulator's extras (scipy not installed):"
        " pip install 'dms[sim]'"
    )
    hide = "import sys; sys.modules['matplotlib'] = None; from dms.cli import main; "
    plot = subprocess.run(
        [sys.executable, "-c", hide + "sys.exit(main(['motivation', 'plot', '--out', 'x.png']))"],
        capture_output=True,
        text=True,
        timeout=60,
        env=ENV,
    )
    assert plot.returncode == 1
    assert (
        "dms motivation plot needs the simulator's extras (matplotlib not installed)" in plot.stderr
    )
