"""``dms ros2`` started from an environment that holds another ROS 2: it still bridges.

A process running on the ROS 2 wheels passes their re-exec guard on
(``_ROS_WHEELS_BOOTSTRAP_COMPLETE``), and a shell that sourced
``/opt/ros/<distro>/setup.bash`` passes that ROS's ``LD_LIBRARY_PATH``,
``AMENT_PREFIX_PATH`` and ``PYTHONPATH``. Here a folder of bogus ``librcl*.so`` files and
a bogus ``rclpy`` stand for that other ROS. The bridge, its daemon and a plain rclpy node
run as in ``test_ros2.py`` (Fast DDS on loopback, Zenoh on 127.0.0.1).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from dms.ros2_cli import VENV, WHEELS_GUARD, bridge_environment
from tests.integration.harness import DaemonProcess, client_session
from tests.integration.test_ros2 import BridgeProcess, Probe, bridge_python, ros_env

__all__ = ["bridge_python"]  # the fixture, shared with test_ros2.py

LIBRARIES = ("librcl.so", "librcl_action.so", "librcl_lifecycle.so", "librmw.so", "librcutils.so")


def another_ros(root: Path) -> dict[str, str]:
    """A ROS 2 of bogus files under ``root``, as sourcing its setup.bash would announce
    it; the wheels' guard as a process running on them would pass it on."""
    lib = root / "lib"
    lib.mkdir(parents=True)
    for name in LIBRARIES:
        (lib / name).write_text("not a library\n")
    python = lib / "python3.11" / "site-packages"
    (python / "rclpy").mkdir(parents=True)
    (python / "rclpy" / "__init__.py").write_text("raise ImportError('the other ROS rclpy')\n")
    return {
        WHEELS_GUARD: "1",
        "LD_LIBRARY_PATH": str(lib),
        "AMENT_PREFIX_PATH": str(root),
        "CMAKE_PREFIX_PATH": str(root),
        "PYTHONPATH": str(python),
        "ROS_DISTRO": "elsewhere",
    }


def test_the_bridges_environment_leaves_another_ros_out(tmp_path: Path) -> None:
    inherited = another_ros(tmp_path / "other")
    plain = tmp_path / "plain"
    plain.mkdir()
    (plain / "libsomething.so").write_text("")
    inherited["LD_LIBRARY_PATH"] += f":/opt/ros/jazzy/lib:{plain}"
    inherited["PYTHONPATH"] += f":/opt/ros/jazzy/lib/python3.12/site-packages:{plain}"
    inherited["ROS_DOMAIN_ID"] = "42"
    env = bridge_environment(inherited, VENV)
    libraries = env["LD_LIBRARY_PATH"].split(os.pathsep)
    assert libraries[0] == str(VENV / "lib") and str(plain) in libraries
    assert any(entry.endswith("ros_rcl.libs") for entry in libraries), libraries
    assert not [entry for entry in libraries if "other" in entry or entry.startswith("/opt/ros")]
    assert env["PYTHONPATH"] == str(plain)
    for name in ("AMENT_PREFIX_PATH", "CMAKE_PREFIX_PATH", "ROS_DISTRO"):
        assert name not in env, name
    assert env["ROS_DOMAIN_ID"] == "42" and env[WHEELS_GUARD] == "1"
    only_ros = another_ros(tmp_path / "third")["PYTHONPATH"]
    assert "PYTHONPATH" not in bridge_environment({"PYTHONPATH": only_ros}, VENV)


@pytest.mark.integration
def test_dms_ros2_bridges_from_an_environment_holding_another_ros(
    bridge_python: Path, tmp_path: Path
) -> None:
    daemon = DaemonProcess(tmp_path)
    session = client_session(daemon.port)
    env = ros_env()
    bridge: BridgeProcess | None = None
    probe: Probe | None = None
    try:
        daemon.start(session)
        bridge = BridgeProcess(
            daemon.port, {**env, **another_ros(tmp_path / "other")}, tmp_path / "bridge.log"
        )
        probe = Probe(bridge_python, env)
        probe.sub("/robots/mini/dms/state", qos="latched")
        probe.message("/robots/mini/dms/state")  # the bridge is there and active
        probe.sub("/robots/mini/dms/decision")
        mark = probe.mark()
        request = {"action": "start", "activity": "jokes", "by": "ros"}
        probe.pub("/robots/mini/request", {"data": json.dumps(request)})
        decision = probe.message(
            "/robots/mini/dms/decision",
            lambda d: d["action"] == "start" and d["activity"] == "jokes",
            start=mark,
        )
        assert decision["reason"] == "user_request"
        code = bridge.stop()
        assert code == 0, bridge.log.read_text()
        assert "ImportError" not in bridge.log.read_text()
    finally:
        if probe is not None:
            probe.close()
        if bridge is not None and bridge.proc.poll() is None:
            bridge.stop()
        daemon.kill()
        session.close()


@pytest.mark.integration
def test_a_bridge_that_cannot_configure_says_why(bridge_python: Path, tmp_path: Path) -> None:
    """No daemon at the endpoint: the one line names the Zenoh session, not "see above"."""
    from tests.integration.harness import free_port

    bridge = BridgeProcess(free_port(), ros_env(), tmp_path / "bridge.log")
    try:
        code = bridge.proc.wait(60)
    finally:
        bridge.stop()
    said = bridge.log.read_text()
    assert code == 1, said
    last = said.strip().splitlines()[-1]
    assert last.startswith("dms ros2: the node could not be configured: cannot open the Zenoh"), (
        said
    )
