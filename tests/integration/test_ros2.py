"""From outside: ``dms ros2`` between a real daemon and real ROS 2 nodes.

The bridge runs as ``dms ros2`` does it, in its own environment (``.venv-ros2``, made
here as ``dms ros2 --prepare`` makes it); the ROS 2 side of each test is
``dms_ros2.probe``, a plain rclpy node in that environment driven by JSON lines. Fast
DDS keeps to loopback (the profile ``ros2/loopback_fastdds.xml``: UDP on 127.0.0.1 and
shared memory, a test asserts it from the processes' sockets) in a domain of the test's
own; Zenoh runs on 127.0.0.1. Every wait is for a message or a service's answer, with
a deadline; only a topic's silence is watched for a set time.
"""

from __future__ import annotations

import ipaddress
import itertools
import json
import os
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from dms.kernel.errors import ConfigError
from dms.ros2_cli import CHECKOUT, prepare
from tests.integration.harness import Collector, DaemonProcess, client_session, put

pytestmark = pytest.mark.integration

STRING = "std_msgs/msg/String"
WAIT_S = 60.0
"""Fast DDS discovery on loopback takes a few seconds; the margin is for a loaded CI."""
STOP_S = 10.0
"""How long the bridge may take to exit on SIGTERM: under 2 s unloaded, the rest is margin
for a loaded CI (a bridge that hangs takes forever, not 11 s)."""
_domains = itertools.count((os.getpid() % 40) * 2 + 10)


@pytest.fixture(scope="module")
def bridge_python() -> Path:
    """The bridge's environment, made as the docs say; the tests skip only when it
    cannot be made (no network and no cache, a Python the wheels are not built for)."""
    try:
        return prepare(echo=False)
    except ConfigError as error:
        pytest.skip(f"the ROS 2 bridge's environment cannot be made: {error}")


LOOPBACK_PROFILE = CHECKOUT / "ros2" / "loopback_fastdds.xml"
OVERRIDES = (
    "ROS_LOCALHOST_ONLY",
    "ROS_STATIC_PEERS",
    "ROS_DISCOVERY_SERVER",
    "ROS_SUPER_CLIENT",
    "FASTRTPS_DEFAULT_PROFILES_FILE",  # Fast DDS 2.x's name, deprecated by the 3.x wheels
)
"""Settings of a developer's shell that would change discovery under the profile."""


def ros_env(domain: int | None = None) -> dict[str, str]:
    """Fast DDS on loopback only, in a domain no other test uses.

    ``SYSTEM_DEFAULT`` leaves discovery to the profile: with ``LOCALHOST``, rmw_fastrtps
    adds a UDP transport of its own beside it, and each process then also holds a socket
    on 0.0.0.0 and one on the machine's address (the loopback test below would fail).
    """
    env = {name: value for name, value in os.environ.items() if name not in OVERRIDES}
    env.update(
        ROS_DOMAIN_ID=str(next(_domains) if domain is None else domain),
        ROS_AUTOMATIC_DISCOVERY_RANGE="SYSTEM_DEFAULT",
        RMW_IMPLEMENTATION="rmw_fastrtps_cpp",
        FASTDDS_DEFAULT_PROFILES_FILE=str(LOOPBACK_PROFILE),
        PYTHONUNBUFFERED="1",
    )
    return env


def _proc_address(hex_address: str) -> ipaddress.IPv4Address | ipaddress.IPv6Address:
    """An address as /proc/net/{udp,tcp}[6] writes it: 32-bit words in host order."""
    raw = bytes.fromhex(hex_address)
    words = b"".join(raw[i : i + 4][::-1] for i in range(0, len(raw), 4))
    address = ipaddress.ip_address(words)
    if isinstance(address, ipaddress.IPv6Address) and address.ipv4_mapped is not None:
        return address.ipv4_mapped
    return address


def inet_sockets(pid: int) -> list[tuple[str, str, str]]:
    """``(protocol, local, remote)`` of each IP socket that process ``pid`` holds."""
    inodes = set()
    for fd in Path(f"/proc/{pid}/fd").iterdir():
        try:
            target = os.readlink(fd)
        except OSError:  # closed meanwhile
            continue
        if target.startswith("socket:["):
            inodes.add(target[len("socket:[") : -1])
    found = []
    for protocol in ("udp", "udp6", "tcp", "tcp6"):
        table = Path(f"/proc/{pid}/net/{protocol}").read_text().splitlines()[1:]
        for row in table:
            fields = row.split()
            if fields[9] in inodes:
                ends = []
                for end in fields[1:3]:
                    address, port = end.split(":")
                    ends.append(f"{_proc_address(address)}:{int(port, 16)}")
                found.append((protocol, ends[0], ends[1]))
    return found


def off_loopback(sockets: list[tuple[str, str, str]]) -> list[tuple[str, str, str]]:
    """The sockets bound, or connected, to anything but loopback (``0.0.0.0`` included)."""

    def loopback(end: str) -> bool:
        return ipaddress.ip_address(end.rpartition(":")[0]).is_loopback

    def unconnected(end: str) -> bool:
        return ipaddress.ip_address(end.rpartition(":")[0]).is_unspecified

    return [s for s in sockets if not loopback(s[1]) or not (loopback(s[2]) or unconnected(s[2]))]


class Probe:
    """``python -m dms_ros2.probe``: subscribe, publish, act as the robot; its events
    (``{"event", "topic", "msg", "t"}``) are kept and waited for."""

    def __init__(self, python: Path, env: dict[str, str]) -> None:
        self.events: list[dict[str, Any]] = []
        self._cond = threading.Condition()
        self.proc = subprocess.Popen(
            [str(python), "-m", "dms_ros2.probe"],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env=env,
        )
        threading.Thread(target=self._read, daemon=True).start()
        self.wait_for(lambda e: e["event"] == "ready")

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            with self._cond:
                self.events.append(json.loads(line))
                self._cond.notify_all()

    def order(self, **order: Any) -> None:
        assert self.proc.stdin is not None
        self.proc.stdin.write(json.dumps(order) + "\n")
        self.proc.stdin.flush()

    def sub(self, topic: str, kind: str = STRING, qos: str = "events") -> None:
        self.order(op="sub", topic=topic, type=kind, qos=qos)

    def pub(self, topic: str, msg: dict[str, Any], kind: str = STRING) -> None:
        self.order(op="pub", topic=topic, type=kind, msg=msg)

    def mark(self) -> int:
        with self._cond:
            return len(self.events)

    def wait_for(
        self, predicate: Callable[[dict[str, Any]], bool], start: int = 0, timeout: float = WAIT_S
    ) -> dict[str, Any]:
        found: list[dict[str, Any]] = []

        def ready() -> bool:
            found[:] = [e for e in self.events[start:] if predicate(e)][:1]
            return bool(found) or self.proc.poll() is not None

        with self._cond:
            self._cond.wait_for(ready, timeout)
        if not found:
            errors = self.proc.stderr.read() if self.proc.poll() is not None else ""  # type: ignore[union-attr]
            raise AssertionError(
                f"no such ROS 2 event in {timeout} s; last: {self.events[-3:]} {errors}"
            )
        return found[0]

    def message(
        self, topic: str, predicate: Callable[[Any], bool] = lambda _: True, start: int = 0
    ) -> Any:
        """The first message on ``topic`` (a String's JSON decoded) that satisfies it."""

        def payload(event: dict[str, Any]) -> Any:
            msg = event["msg"]
            return json.loads(msg["data"]) if set(msg) == {"data"} else msg

        event = self.wait_for(
            lambda e: e["event"] == "msg" and e["topic"] == topic and predicate(payload(e)), start
        )
        return payload(event)

    def quiet(self, topic: str, start: int, timeout: float) -> bool:
        """True when no message on ``topic`` comes after event ``start`` within ``timeout``."""
        try:
            self.wait_for(
                lambda e: e["event"] == "msg" and e["topic"] == topic, start, timeout=timeout
            )
        except AssertionError:
            return self.proc.poll() is None  # silence, not a probe that died
        return False

    def lifecycle(self, node: str, transition: str | None = None) -> Any:
        """The node's lifecycle state label, after asking it for ``transition`` if given
        (through the standard ``change_state`` and ``get_state`` services)."""
        if transition is not None:
            mark = self.mark()
            self.order(op="change_state", node=node, transition=transition)
            done = self.wait_for(lambda e: e["event"] in ("transition", "error"), mark)
            assert done.get("success") is True, done
        mark = self.mark()
        self.order(op="get_state", node=node)
        return self.wait_for(lambda e: e["event"] in ("state", "error"), mark).get("state")

    def close(self) -> None:
        if self.proc.poll() is None:
            self.order(op="quit")
            try:
                self.proc.wait(20)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(10)


class BridgeProcess:
    """``dms ros2 --robot ID --connect ...`` as a person runs it (it execs the bridge)."""

    def __init__(
        self,
        port: int,
        env: dict[str, str],
        log: Path,
        robot: str = "mini",
        *,
        unconfigured: bool = False,
    ) -> None:
        self.log = log
        self._file = log.open("w")
        endpoint = f"tcp/127.0.0.1:{port}"
        argv = [sys.executable, "-m", "dms.cli", "ros2", "--robot", robot, "--connect", endpoint]
        self.proc = subprocess.Popen(
            [*argv, "--unconfigured"] if unconfigured else argv,
            stdout=self._file,
            stderr=subprocess.STDOUT,
            env=env,
        )

    def stop(self, timeout: float = 20.0) -> int:
        """SIGTERM, then the exit status; -9 when it had to be killed after ``timeout``."""
        if self.proc.poll() is None:
            self.proc.terminate()
        try:
            code = self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait(10)
            code = -9
        self._file.close()
        return code

    def timed_stop(self) -> tuple[int, float]:
        """SIGTERM: the exit status and how long the bridge took to exit."""
        start = time.monotonic()
        code = self.stop(STOP_S)
        return code, time.monotonic() - start


@pytest.fixture(scope="module")
def sim_setup(
    bridge_python: Path, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[tuple[Probe, Any, BridgeProcess]]:
    """A daemon with the simulated Mini, the bridge, a probe and a Zenoh session."""
    tmp = tmp_path_factory.mktemp("ros2")
    daemon = DaemonProcess(tmp)
    session = client_session(daemon.port)
    env = ros_env()
    bridge: BridgeProcess | None = None
    probe: Probe | None = None
    try:
        daemon.start(session)
        bridge = BridgeProcess(daemon.port, env, tmp / "bridge.log")
        probe = Probe(bridge_python, env)
        yield probe, session, bridge
    finally:
        if probe is not None:
            probe.close()
        if bridge is not None:
            bridge.stop()
        daemon.kill()
        session.close()


def test_a_ros_node_sees_the_state_latched_and_the_tick_advance(sim_setup: Any) -> None:
    probe, _session, bridge = sim_setup
    probe.sub("/robots/mini/dms/state", qos="latched")
    first = probe.message("/robots/mini/dms/state")
    later = probe.message("/robots/mini/dms/state", lambda s: s["tick"] > first["tick"])
    assert later["robot"] == "mini" and "inputs" in later
    text = bridge.log.read_text()  # what it bridges is listed at start
    assert "/robots/mini/request [std_msgs/msg/String" in text
    assert "robots/mini/dms/state -> /robots/mini/dms/state" in text


def test_the_bridge_and_a_ros_node_keep_to_loopback(sim_setup: Any) -> None:
    """While messages flow, every IP socket of the bridge and of the ROS 2 node is on
    loopback: none bound to all interfaces or to this machine's network address."""
    probe, _session, bridge = sim_setup
    probe.sub("/robots/mini/dms/state", qos="latched")
    probe.message("/robots/mini/dms/state")
    for pid in (bridge.proc.pid, probe.proc.pid):  # `dms ros2` execs: its pid is the bridge's
        sockets = inet_sockets(pid)
        assert any(protocol == "udp" for protocol, *_ in sockets), sockets  # Fast DDS's
        assert off_loopback(sockets) == [], sockets


def test_socket_tables_are_read_in_host_order() -> None:
    assert str(_proc_address("0100007F")) == "127.0.0.1"
    assert str(_proc_address("020200C0")) == "192.0.2.2"
    assert str(_proc_address("00000000000000000000000001000000")) == "::1"
    assert str(_proc_address("0000000000000000FFFF00000100007F")) == "127.0.0.1"
    sockets = [("udp", "127.0.0.1:7400", "0.0.0.0:0"), ("udp", "0.0.0.0:7000", "0.0.0.0:0")]
    sockets += [("tcp", "127.0.0.1:5000", "192.0.2.9:7447"), ("tcp6", "::1:5001", "::1:7447")]
    assert off_loopback(sockets) == [sockets[1], sockets[2]]


def test_a_request_on_ros_gets_its_start_decision_on_ros(sim_setup: Any) -> None:
    probe, _session, _bridge = sim_setup
    probe.sub("/robots/mini/dms/decision")
    mark = probe.mark()
    request = {"action": "start", "activity": "jokes", "by": "ros"}
    probe.pub("/robots/mini/request", {"data": json.dumps(request)})
    decision = probe.message(
        "/robots/mini/dms/decision",
        lambda d: d["action"] == "start" and d["activity"] == "jokes",
        start=mark,
    )
    assert decision["chosen_by"] == "user" and decision["reason"] == "user_request"


def test_diagnostics_name_each_inputs_health(sim_setup: Any) -> None:
    probe, session, _bridge = sim_setup
    put(session, "perception/user", {"present": True, "user_id": "ann", "ready": True})
    probe.sub("/diagnostics", "diagnostic_msgs/msg/DiagnosticArray")

    def levels(array: dict[str, Any]) -> dict[str, tuple[int, str]]:
        return {s["name"]: (s["level"], s["message"]) for s in array["status"]}

    array = probe.message(
        "/diagnostics", lambda a: levels(a).get("dms mini: input perception/user") == (0, "ok")
    )
    named = levels(array)
    assert named["dms mini: daemon"][0] == 0
    assert named["dms mini: input params/robot"] == (0, "not_published")  # nobody sends it
    assert named["dms mini: robot link"] == (0, "ok")
    assert named["dms mini: storage"] == (0, "ok")


def test_joint_states_carry_the_simulated_minis_joints(sim_setup: Any) -> None:
    probe, _session, _bridge = sim_setup
    probe.sub("/robots/mini/joint_states", "sensor_msgs/msg/JointState")
    joints = probe.message("/robots/mini/joint_states")
    assert joints["name"] == ["head", "hip", "left_arm", "neck", "right_arm"]
    assert len(joints["position"]) == 5


def test_a_face_on_ros_becomes_the_users_face_and_a_marker(sim_setup: Any) -> None:
    probe, session, _bridge = sim_setup
    users = Collector(session, "robots/mini/perception/user")
    probe.sub("/robots/mini/dms/frames", "visualization_msgs/msg/MarkerArray", qos="latched")
    user = {"present": True, "user_id": "bea", "ready": True}
    probe.pub("/robots/mini/perception/user", {"data": json.dumps(user)})
    users.wait_for(lambda u: u.get("user_id") == "bea")
    face = {"header": {"frame_id": "base"}, "pose": {"position": {"x": 0.6, "y": 0.1, "z": 0.4}}}
    probe.pub("/robots/mini/perception/face", face, "geometry_msgs/msg/PoseStamped")
    merged = users.wait_for(lambda u: u.get("face") is not None)
    assert merged["user_id"] == "bea" and merged["ready"] is True
    assert merged["face"]["position"] == {"x": 0.6, "y": 0.1, "z": 0.4}
    markers = probe.message(
        "/robots/mini/dms/frames",
        lambda a: any(m["ns"] == "faces" and m["text"] == "" for m in a["markers"]),
    )
    labels = {m["text"] for m in markers["markers"] if m["type"] == 9}  # TEXT_VIEW_FACING
    assert {"bea", "face:bea"} <= labels


def test_bad_json_on_ros_is_reported_like_a_bad_zenoh_message(sim_setup: Any) -> None:
    probe, session, bridge = sim_setup
    errors = Collector(session, "robots/mini/dms/errors")
    probe.sub("/robots/mini/dms/errors")
    mark = probe.mark()
    probe.pub("/robots/mini/perception/touch", {"data": "{not json"})
    report = errors.wait_for(lambda e: e["key"] == "perception/touch")
    assert probe.message("/robots/mini/dms/errors", start=mark)["error"] == report["error"]
    assert "perception/touch: not JSON" in bridge.log.read_text()


def test_a_ros_node_acting_as_the_robot_runs_an_activity_to_its_end(
    bridge_python: Path, tmp_path: Path
) -> None:
    daemon = DaemonProcess(tmp_path, extra_args=("--robot", "zenoh"))
    session = client_session(daemon.port)
    env = ros_env()
    bridge: BridgeProcess | None = None
    probe: Probe | None = None
    try:
        daemon.start(session)
        bridge = BridgeProcess(daemon.port, env, tmp_path / "bridge.log")
        probe = Probe(bridge_python, env)
        probe.order(op="robot", namespace="/robots/mini")
        probe.sub("/robots/mini/dms/decision")
        probe.sub("/robots/mini/dms/state", qos="latched")
        probe.message("/robots/mini/dms/state")  # the bridge is there
        user = {"present": True, "user_id": "cid", "ready": True}
        probe.pub("/robots/mini/perception/user", {"data": json.dumps(user)})
        mark = probe.mark()
        request = {"action": "start", "activity": "instructions", "by": "ros"}
        probe.pub("/robots/mini/request", {"data": json.dumps(request)})
        probe.message(
            "/robots/mini/dms/decision",
            lambda d: d["action"] == "start" and d["activity"] == "instructions",
            start=mark,
        )
        probe.message(
            "/robots/mini/dms/decision",
            lambda d: d["action"] == "complete" and d["activity"] == "instructions",
            start=mark,
        )
        commands = [
            e["msg"]
            for e in probe.events[mark:]
            if e["event"] == "msg" and e["topic"] == "/robots/mini/robot/command"
        ]
        assert any(c["channel"] == "speech" for c in commands)
        code, took = bridge.timed_stop()  # SIGTERM: a clean exit, at once
        assert code == 0, (code, took, bridge.log.read_text())
        assert daemon.terminate() == 0
    finally:
        if probe is not None:
            probe.close()
        if bridge is not None and bridge.proc.poll() is None:
            bridge.stop()
        daemon.kill()
        session.close()


QUIET_S = 2.0
"""How long a topic must stay silent to count as stopped: four of the daemon's 2 Hz ticks."""


@pytest.fixture(scope="module")
def lifecycle_setup(
    bridge_python: Path, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[tuple[DaemonProcess, Probe, dict[str, str], Path]]:
    """A daemon with the simulated Mini and a probe, for bridges started ``--unconfigured``."""
    tmp = tmp_path_factory.mktemp("ros2-lifecycle")
    daemon = DaemonProcess(tmp)
    session = client_session(daemon.port)
    env = ros_env()
    probe: Probe | None = None
    try:
        daemon.start(session)
        probe = Probe(bridge_python, env)
        yield daemon, probe, env, tmp
    finally:
        if probe is not None:
            probe.close()
        daemon.kill()
        session.close()


def test_a_lifecycle_manager_drives_the_bridge_through_its_states(lifecycle_setup: Any) -> None:
    """Through the standard lifecycle services, as ``ros2 lifecycle set`` does: the state
    flows only while the node is active, and SIGTERM after cleanup exits 0 at once."""
    daemon, probe, env, tmp = lifecycle_setup
    node, state_topic = "/robots/mini/dms_bridge", "/robots/mini/dms/state"
    start = probe.mark()
    bridge = BridgeProcess(daemon.port, env, tmp / "cycle.log", unconfigured=True)
    try:
        probe.sub(state_topic, qos="latched")
        assert probe.lifecycle(node) == "unconfigured"
        assert probe.quiet(state_topic, start, QUIET_S)
        assert probe.lifecycle(node, "configure") == "inactive"
        mark = probe.mark()
        assert probe.lifecycle(node, "activate") == "active"
        first = probe.message(state_topic, start=mark)
        probe.message(state_topic, lambda s: s["tick"] > first["tick"], start=mark)
        assert probe.lifecycle(node, "deactivate") == "inactive"
        assert probe.quiet(state_topic, probe.mark(), QUIET_S)
        assert probe.lifecycle(node, "cleanup") == "unconfigured"
        code, took = bridge.timed_stop()
        assert code == 0, (code, took, bridge.log.read_text())
    finally:
        if bridge.proc.poll() is None:
            bridge.stop()


@pytest.mark.parametrize(
    ("robot", "transitions", "state"),
    [
        ("unconfigured", (), "unconfigured"),
        ("inactive", ("configure",), "inactive"),
        ("active", ("configure", "activate"), "active"),
        ("cleaned_up", ("configure", "activate", "deactivate", "cleanup"), "unconfigured"),
        ("finalized", ("configure", "activate", "shutdown"), "finalized"),
    ],
)
def test_sigterm_stops_the_bridge_cleanly_in_every_lifecycle_state(
    lifecycle_setup: Any, robot: str, transitions: tuple[str, ...], state: str
) -> None:
    """A bridge of its own per state (the robot id names it, so no service of an earlier
    one answers); the state is read back before the signal."""
    daemon, probe, env, tmp = lifecycle_setup
    node = f"/robots/{robot}/dms_bridge"
    bridge = BridgeProcess(daemon.port, env, tmp / f"{robot}.log", robot, unconfigured=True)
    try:
        assert probe.lifecycle(node) == "unconfigured"
        for transition in transitions:
            probe.lifecycle(node, transition)
        assert probe.lifecycle(node) == state
        code, took = bridge.timed_stop()
        assert code == 0, (code, took, bridge.log.read_text())
    finally:
        if bridge.proc.poll() is None:
            bridge.stop()


def test_rules_check_still_works_in_the_daemons_environment(bridge_python: Path) -> None:
    """The bridge's environment holds lark-parser 0.12; the daemon's keeps lark 1.x."""
    assert bridge_python.parent.parent != Path(sys.prefix)
    rules = CHECKOUT / "dms" / "rules" / "examples" / "decisions.dmsl"
    done = subprocess.run(
        [sys.executable, "-m", "dms.cli", "rules", "check", str(rules)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    bridge_lark = subprocess.run(
        [str(bridge_python), "-c", "import lark; print(lark.__version__)"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert bridge_lark.stdout.startswith("0."), bridge_lark  # the reason for two environments
