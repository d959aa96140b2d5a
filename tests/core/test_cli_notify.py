"""systemd's notify protocol (dms/notify.py): the datagrams, their order in the daemon's
start, the watchdog's pace; and the log formats (dms/logs.py) and the configuration's
precedence (flags > environment > TOML > defaults) as ``dms run`` applies them.

The real daemon under a real notify socket is tests/integration/test_cli_daemon.py.
"""

from __future__ import annotations

import io
import json
import logging
import os
import socket
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest

from dms.config import load_config
from dms.daemon import Daemon
from dms.kernel.errors import ConfigError
from dms.kernel.ports import RobotPort
from dms.local_bus import InMemoryBus
from dms.logs import setup_logging
from dms.notify import Notifier


@pytest.fixture
def listener() -> Iterator[tuple[socket.socket, str]]:
    folder = tempfile.mkdtemp(prefix="dms-n-", dir="/tmp")
    path = os.path.join(folder, "s")
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    sock.bind(path)
    sock.settimeout(5.0)
    try:
        yield sock, path
    finally:
        sock.close()
        os.unlink(path)
        os.rmdir(folder)


def _states(sock: socket.socket) -> dict[str, str]:
    return dict(line.split("=", 1) for line in sock.recv(4096).decode().splitlines())


def test_datagrams_and_the_watchdog_pace(listener: tuple[socket.socket, str]) -> None:
    sock, path = listener
    now = [100.0]
    notifier = Notifier({"NOTIFY_SOCKET": path, "WATCHDOG_USEC": "2000000"}, lambda: now[0])
    assert notifier.ready("up")
    assert _states(sock) == {"READY": "1", "MAINPID": str(os.getpid()), "STATUS": "up"}
    assert notifier.watchdog() and _states(sock) == {"WATCHDOG": "1"}
    now[0] += 0.49
    assert not notifier.watchdog()  # a quarter of 2 s has not passed
    now[0] += 0.01
    assert notifier.watchdog() and _states(sock) == {"WATCHDOG": "1"}
    assert notifier.stopping() and _states(sock) == {"STOPPING": "1"}
    notifier.close()


def test_ready_is_sent_after_alive_is_declared(
    listener: tuple[socket.socket, str], tmp_path: Path
) -> None:
    sock, path = listener
    bus = InMemoryBus("mini")
    seen: list[tuple[str, bool]] = []

    class Watching(Notifier):
        def send(self, **states: str | int) -> bool:
            seen.extend((name, bus.alive) for name in states)
            return super().send(**states)

    settings = load_config(db=f"sqlite:///{tmp_path / 'dms.db'}", use_environment=False)
    daemon = Daemon(
        settings,
        print_decisions=False,
        bus=bus,
        sim_robot=_robot,
        notifier=Watching({"NOTIFY_SOCKET": path, "WATCHDOG_USEC": "1000000"}),
    )
    try:
        daemon.start()
    finally:
        daemon.close()
    assert ("READY", True) in seen and ("READY", False) not in seen
    assert _states(sock)["READY"] == "1"


def _robot(seed: int) -> RobotPort:
    from sim.robot import SimRobot

    return SimRobot(rng_seed=seed)


def test_json_and_text_lines_carry_the_structured_fields() -> None:
    out = io.StringIO()
    setup_logging("info", "json", out, robot_id="mini")
    log = logging.getLogger("dms.test")
    log.info("reloaded %d", 2, extra={"event": "reload"})
    logging.getLogger("alembic.x").info("not the daemon's")
    log.debug("hidden")
    lines = [json.loads(line) for line in out.getvalue().splitlines()]
    assert len(lines) == 1
    line = lines[0]
    assert (line["level"], line["logger"], line["message"]) == ("info", "dms.test", "reloaded 2")
    assert (line["event"], line["robot_id"]) == ("reload", "mini")
    out = io.StringIO()
    setup_logging("debug", "text", out)
    log.debug("x", extra={"missed": 3, "why": "two words"})
    assert out.getvalue().rstrip().endswith('DEBUG dms.test: x missed=3 why="two words"')
    setup_logging("warning", "text")


def test_flags_over_environment_over_toml_over_defaults(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    toml = tmp_path / "dms.toml"
    toml.write_text(
        'robot_id = "toml"\nseed = 1\n[controller]\ntick_period_s = 0.3\nquestion_every = 7\n'
        '[rules]\nfiles = ["mine.dmsl"]\n'
    )
    for name in [n for n in os.environ if n.startswith("DMS_")]:
        monkeypatch.delenv(name)
    monkeypatch.setenv("DMS_ROBOT_ID", "env")
    monkeypatch.setenv("DMS_SEED", "2")
    monkeypatch.setenv("DMS_CONTROLLER__TICK_PERIOD_S", "0.25")
    monkeypatch.setenv("DMS_ZENOH__CONNECT", '["tcp/10.0.0.2:7447"]')
    monkeypatch.setenv("DMS_TEST_SOMETHING_ELSE", "ignored")
    settings = load_config(toml, seed=3)
    assert settings.robot_id == "env"  # environment over TOML
    assert settings.seed == 3  # flag over environment
    assert settings.controller.tick_period_s == 0.25
    assert settings.controller.question_every == 7  # the TOML's other fields stay
    assert settings.controller.session_questions == 4  # default
    assert settings.zenoh.connect == ["tcp/10.0.0.2:7447"]
    assert settings.zenoh.listen == ["tcp/127.0.0.1:7447"]
    assert settings.rules.files == [tmp_path / "mine.dmsl"]  # relative to the file
    assert load_config(toml, use_environment=False).robot_id == "toml"
    monkeypatch.setenv("DMS_CONTROLLER__TICK_PERIOD_S", "60")
    with pytest.raises(ConfigError, match=r"^DMS_CONTROLLER__TICK_PERIOD_S \(environment\): "):
        load_config(toml)


def test_an_abstract_notify_socket() -> None:
    """``@name`` is Linux's abstract namespace (what systemd may hand out)."""
    name = f"dms-notify-test-{os.getpid()}"
    with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as sock:
        sock.bind("\0" + name)
        sock.settimeout(5.0)
        notifier = Notifier({"NOTIFY_SOCKET": "@" + name})
        assert notifier.enabled and notifier.watchdog_every_s is None  # no WATCHDOG_USEC
        assert not notifier.watchdog()
        assert notifier.stopping() and _states(sock) == {"STOPPING": "1"}
        notifier.close()
