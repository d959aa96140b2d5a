"""A secured deployment from ``dms secure init``, tried with real TLS sessions.

One daemon process runs with ``--zenoh-config DIR/dms.json5``; the tests open Zenoh
sessions from the role files as other programs would (``zenoh.Config.from_file``). A
"rogue" session holds a role's certificate but drops its file's access control, as a
certificate holder who edits their own config would: what it cannot do is what the
daemon itself refuses. Every "cannot" is proved against a positive control sent after
it on the same session: the control's effect is awaited, then the denied message is
shown to have had none.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

import pytest
import zenoh

from dms import secure
from tests.integration.harness import (
    Collector,
    DaemonProcess,
    free_port,
    token_deleted,
    wait_token,
)

pytestmark = pytest.mark.integration

ROBOT = "robots/mini"
FAST_RETRY = "{period_init_ms: 50, period_max_ms: 50, period_increase_factor: 1}"


def role_config(directory: Path, role: str, rogue: bool = False) -> zenoh.Config:
    """The shipped file of ``role``, as another program opens it; ``rogue`` turns its own
    access control off. The connect retry is shortened only so that a test does not wait
    Zenoh's default second for a daemon that is starting."""
    if rogue:
        text = (directory / f"{role}.json5").read_text()
        lines = [line for line in text.splitlines() if not line.startswith("//")]
        conf = json.loads("\n".join(lines))
        conf["access_control"]["enabled"] = False
        config = zenoh.Config.from_json5(json.dumps(conf))
    else:
        config = zenoh.Config.from_file(str(directory / f"{role}.json5"))
    config.insert_json5("connect/retry", FAST_RETRY)
    return config


class SecuredDaemon(DaemonProcess):
    """``dms run --zenoh-config DIR/dms.json5``: the file's TLS endpoint, no ``--listen``."""

    def __init__(self, tmp: Path, zenoh_file: Path) -> None:
        super().__init__(tmp, extra_config="[privacy]\nserve_profiles = true\n")
        self.zenoh_file = zenoh_file

    def start(self, session: zenoh.Session) -> None:
        env = dict(os.environ, PYTHONUNBUFFERED="1")
        self._log_file = self.log.open("w")
        self.proc = subprocess.Popen(
            [
                *(sys.executable, "-m", "dms.cli", "run", "--config", str(self.config)),
                *("--db", self.db, "--zenoh-config", str(self.zenoh_file)),
            ],
            stdout=self._log_file,
            stderr=subprocess.STDOUT,
            text=True,
            env=env,
        )
        try:
            wait_token(session, f"{ROBOT}/alive/dms")
        except AssertionError:
            self.proc.kill()
            raise AssertionError(f"daemon never became ready:\n{self.log.read_text()}") from None


@dataclass
class Deployment:
    directory: Path
    port: int
    daemon: SecuredDaemon
    sessions: dict[str, zenoh.Session]

    def session(self, role: str, rogue: bool = False) -> zenoh.Session:
        """A session of ``role`` that has seen ``alive/dms`` (so it is connected)."""
        name = f"{role}{'-rogue' if rogue else ''}"
        if name not in self.sessions:
            session = zenoh.open(role_config(self.directory, role, rogue))
            self.sessions[name] = session
            wait_token(session, f"{ROBOT}/alive/dms")
        return self.sessions[name]


@pytest.fixture(scope="module")
def deployment(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Deployment]:
    tmp = tmp_path_factory.mktemp("secure")
    port = free_port()
    directory = tmp / "sec"
    secure.init(directory, "mini", f"tls/127.0.0.1:{port}")
    daemon = SecuredDaemon(tmp, directory / "dms.json5")
    created = subprocess.run(  # the users commands never create a database
        [sys.executable, "-m", "dms.cli", "db", "upgrade", "--db", daemon.db],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert created.returncode == 0, created.stderr
    added = subprocess.run(
        [
            *(sys.executable, "-m", "dms.cli", "users", "add", "alice"),
            *("--set", "name=Alice", "--db", daemon.db),
        ],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert added.returncode == 0, added.stderr
    deployment = Deployment(directory, port, daemon, {})
    admin = zenoh.open(role_config(directory, "admin"))
    deployment.sessions["admin"] = admin
    try:
        daemon.start(admin)
        yield deployment
        assert daemon.terminate() == 0
    finally:
        daemon.kill()
        for session in deployment.sessions.values():
            session.close()


def _put(session: zenoh.Session, key: str, payload: dict[str, Any]) -> None:
    session.put(
        f"{ROBOT}/{key}",
        json.dumps(payload).encode(),
        encoding=zenoh.Encoding.APPLICATION_JSON,
        congestion_control=zenoh.CongestionControl.BLOCK,
    )


def _get(
    session: zenoh.Session,
    key: str,
    payload: dict[str, Any] | None = None,
    timeout: float = 5.0,
) -> list[tuple[bool, Any]]:
    """Every reply to ``get`` (it returns once the query is complete: all answered, or
    the timeout for a query that reached a queryable but was never answered)."""
    out: list[tuple[bool, Any]] = []
    data = json.dumps(payload).encode() if payload is not None else None
    for reply in session.get(f"{ROBOT}/{key}", payload=data, timeout=timeout):
        sample = reply.ok if reply.ok is not None else reply.err
        out.append((reply.ok is not None, json.loads(sample.payload.to_bytes())))
    return out


def _user(state: dict[str, Any]) -> str | None:
    user = state.get("user")
    return user["id"] if isinstance(user, dict) else None


def test_a_peer_without_a_certificate_cannot_connect(deployment: Deployment) -> None:
    directory, port = deployment.directory, deployment.port
    # TLS with the right CA, but no certificate of its own to show ...
    no_cert = json.loads(
        "\n".join(
            line
            for line in (directory / "app.json5").read_text().splitlines()
            if not line.startswith("//")
        )
    )
    tls = no_cert["transport"]["link"]["tls"]
    for field in ("connect_private_key", "connect_certificate"):
        del tls[field]
    tls["enable_mtls"] = False
    no_cert["access_control"]["enabled"] = False
    # ... and plain TCP to the TLS port.
    plain = {
        "mode": "peer",
        "connect": {"endpoints": [f"tcp/127.0.0.1:{port}"]},
        "listen": {"endpoints": []},
        "scouting": {"multicast": {"enabled": False}, "gossip": {"enabled": False}},
    }
    strangers = [zenoh.open(zenoh.Config.from_json5(json.dumps(c))) for c in (no_cert, plain)]
    try:
        perception = deployment.session("perception")
        states = Collector(deployment.session("app"), f"{ROBOT}/dms/state")
        # Each stranger sets the robot's parameters; then perception, with its certificate,
        # sets the environment's. Neither was set before (both "not_published").
        for stranger in strangers:
            _put(stranger, "params/robot", {"batterylevel": 5})
            assert _get(stranger, "dms/state", timeout=1.0) == []
        _put(perception, "params/env", {"noise_db": 40})
        seen = states.wait_for(lambda s: s["inputs"].get("params/env") == "ok")
        states.wait_for(lambda s: s["tick"] > seen["tick"])  # one more tick for margin
        robot_params = [s["inputs"].get("params/robot") for s in states.messages]
        assert set(robot_params) == {"not_published"}
        for stranger in strangers:
            assert list(stranger.info.peers_zid()) == []
        assert list(perception.info.peers_zid()) != []
    finally:
        for stranger in strangers:
            stranger.close()


@pytest.mark.parametrize("rogue", [False, True], ids=["shipped", "rogue"])
def test_perception_cannot_put_a_request_but_its_perception_arrives(
    deployment: Deployment, rogue: bool
) -> None:
    perception = deployment.session("perception", rogue)
    app = deployment.session("app")
    decisions = Collector(app, f"{ROBOT}/dms/decision")
    states = Collector(app, f"{ROBOT}/dms/state")
    user = f"dora{int(rogue)}"
    activity = "quiz" if rogue else "bingo"  # a request for a running one decides nothing
    _put(perception, "request", {"action": "start", "activity": activity, "by": "perception"})
    _put(perception, "perception/user", {"present": True, "user_id": user, "ready": True})
    seen = states.wait_for(lambda s: _user(s) == user)
    states.wait_for(lambda s: s["tick"] > seen["tick"])
    assert not [d for d in decisions.messages if d["reason"] == "user_request"]
    _put(perception, "perception/user", {"present": False, "user_id": None, "ready": False})
    states.wait_for(lambda s: _user(s) is None, start=states.mark())


def test_input_tokens_are_taken_from_their_own_role_only(deployment: Deployment) -> None:
    """An input module's ``alive/<key>`` token reaches the daemon (its input shows in
    ``inputs``, and is ``missing`` once the token goes); perception's certificate cannot
    declare the robot's token, even with its own access control off."""
    perception = deployment.session("perception", rogue=True)
    robot = deployment.session("robot")
    states = Collector(deployment.session("app"), f"{ROBOT}/dms/state")
    liveliness = perception.liveliness()
    forged = liveliness.declare_token(f"{ROBOT}/alive/robot/feedback")
    touch = liveliness.declare_token(f"{ROBOT}/alive/perception/touch")
    seen = states.wait_for(lambda s: s["inputs"].get("perception/touch") == "ok")
    states.wait_for(lambda s: s["tick"] > seen["tick"])
    assert not [s for s in states.messages if "robot/feedback" in s["inputs"]]
    touch.undeclare()
    states.wait_for(lambda s: s["inputs"].get("perception/touch") == "missing")
    feedback = robot.liveliness().declare_token(f"{ROBOT}/alive/robot/feedback")
    states.wait_for(lambda s: s["inputs"].get("robot/feedback") == "ok")
    feedback.undeclare()
    forged.undeclare()
    states.wait_for(lambda s: s["inputs"].get("robot/feedback") == "missing")


def test_an_app_cannot_read_profiles_or_agendas_but_admin_can(deployment: Deployment) -> None:
    for rogue in (False, True):
        app = deployment.session("app", rogue)
        assert _get(app, "users/alice") == []
        assert _get(app, "users/*") == []
        assert _get(app, "agenda/alice") == []
        control = _get(app, "dms/state")
        assert len(control) == 1 and control[0][0] and control[0][1]["robot"] == "mini"
    admin = deployment.session("admin")
    at = (datetime.now(UTC) + timedelta(days=1)).isoformat()
    reminder = {"op": "add", "kind": "reminder", "at": at}
    app = deployment.session("app", rogue=True)
    assert _get(app, "agenda/alice", {**reminder, "text": "from the app"}) == []
    [(ok, added)] = _get(admin, "agenda/alice", {**reminder, "text": "from admin"})
    assert ok, added
    [(ok, agenda)] = _get(admin, "agenda/alice")
    assert ok and [item["text"] for item in agenda["items"]] == ["from admin"]
    [(ok, profile)] = _get(admin, "users/alice")
    assert ok and json.dumps(profile).count("Alice") >= 1
    [(ok, listing)] = _get(admin, "users/*")
    assert ok and "alice" in listing["users"]


def test_an_app_watches_and_requests_the_robot_gets_commands(deployment: Deployment) -> None:
    app = deployment.session("app")
    robot = deployment.session("robot")
    decisions = Collector(app, f"{ROBOT}/dms/decision")
    states = Collector(app, f"{ROBOT}/dms/state")
    app_commands = Collector(app, f"{ROBOT}/robot/command")
    robot_commands = Collector(robot, f"{ROBOT}/robot/command")
    _put(app, "request", {"action": "start", "activity": "jokes", "by": "caregiver"})
    decisions.wait_for(
        lambda d: (
            d["action"] == "start" and d["activity"] == "jokes" and d["reason"] == "user_request"
        )
    )
    robot_commands.wait_count(1)
    mark = states.mark()
    states.wait_for(lambda s: True, start=mark)
    states.wait_for(lambda s: True, start=mark + 1)
    assert app_commands.messages == []
    _put(app, "request", {"action": "cancel", "activity": "jokes", "by": "caregiver"})
    decisions.wait_for(lambda d: d["action"] == "cancel" and d["activity"] == "jokes")


def test_sigterm_still_stops_a_secured_daemon(tmp_path: Path) -> None:
    """``alive/dms`` goes away on SIGTERM and the daemon exits 0 (a sanity check that
    the secured link does not hold the shutdown)."""
    port = free_port()
    secure.init(tmp_path / "sec", "mini", f"tls/127.0.0.1:{port}")
    daemon = SecuredDaemon(tmp_path, tmp_path / "sec" / "dms.json5")
    app = zenoh.open(role_config(tmp_path / "sec", "app"))
    try:
        daemon.start(app)
        assert daemon.proc is not None
        with token_deleted(app, f"{ROBOT}/alive/dms"):
            daemon.proc.send_signal(signal.SIGTERM)
        code = daemon.proc.wait(20)
        assert code == 0, daemon.log.read_text()[-4000:]
    finally:
        daemon.kill()
        app.close()


def test_the_commands_refuse_a_symlink_planted_in_the_folder(tmp_path: Path) -> None:
    """``dms secure init --force`` and ``renew`` as a shell runs them: a link planted
    where a key goes is named in one line, and the file it points to is never written."""
    folder, victim = tmp_path / "sec", tmp_path / "victim"
    secure.init(folder, "mini")

    def dms_secure(*args: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            [sys.executable, "-m", "dms.cli", "secure", *args],
            capture_output=True,
            text=True,
            timeout=60,
        )

    for planted, args in [
        ("ca.key", ("init", str(folder), "--robot-id", "mini", "--force")),
        ("robot.key", ("renew", str(folder), "robot")),
    ]:
        (folder / planted).unlink()
        (folder / planted).symlink_to(victim)
        done = dms_secure(*args)
        assert done.returncode == 1
        assert done.stderr.strip().splitlines() == [
            f"dms: {folder / planted} is a symbolic link; refusing to write through it"
        ]
        assert not victim.exists()
        (folder / planted).unlink()
    assert dms_secure("init", str(folder), "--robot-id", "mini", "--force").returncode == 0


def test_only_admin_may_try_a_behavior_from_the_studio(deployment: Deployment) -> None:
    """A studio's try moves the robot: an app, even one that forges its role, gets no
    answer; admin gets the daemon's."""
    for rogue in (False, True):
        app = deployment.session("app", rogue)
        assert _get(app, "studio/try", {"op": "frames"}) == []
    admin = deployment.session("admin")
    [(ok, reply)] = _get(admin, "studio/try", {"op": "frames"})
    assert ok and isinstance(reply["frames"], list), reply
