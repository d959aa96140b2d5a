"""The checks behind the operator's commands, without a bus: endpoints, requests, config
errors, the Foxglove subprotocol's two names, the rotations the daemon makes without
scipy, and the extras a command needs."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from dms.bus import check_endpoint
from dms.cli import SIM_EXTRAS, missing_sim_extras
from dms.config import load_config
from dms.foxglove_bridge import negotiate, rename_back
from dms.kernel.errors import ConfigError
from dms.kernel.frames import pose
from dms.operator_cli import absolute_key, build_request
from sim.record_cli import default_name


@pytest.mark.parametrize(
    "endpoint", ["tcp/127.0.0.1:7447", "tcp/[::1]:7447", "tls/robot.local:7447", "udp/0.0.0.0:0"]
)
def test_zenoh_locators_are_endpoints(endpoint: str) -> None:
    assert check_endpoint(endpoint) == endpoint


@pytest.mark.parametrize(
    "endpoint", ["127.0.0.1:18508", "tcp/127.0.0.1", "tcp/127.0.0.1:99999", "tcp/", ""]
)
def test_an_endpoint_without_protocol_or_port_is_refused_naming_the_form(endpoint: str) -> None:
    with pytest.raises(ConfigError) as caught:
        check_endpoint(endpoint)
    assert str(caught.value) == f"`{endpoint}`: an endpoint is `tcp/HOST:PORT`"


@pytest.mark.parametrize(
    "key", ["/robots/mini/dms/state", "robots/mini/dms/state", "dms/state", "/dms/state"]
)
def test_a_key_is_the_same_with_or_without_slash_absolute_or_relative(key: str) -> None:
    assert absolute_key("mini", key) == "robots/mini/dms/state"


def test_a_request_is_checked_before_it_is_sent() -> None:
    assert build_request("start", "quiz", "cli") == {
        "action": "start",
        "activity": "quiz",
        "by": "cli",
    }
    assert build_request("reload", None, "cli") == {"action": "reload_rules", "by": "cli"}
    with pytest.raises(ConfigError, match="did you mean quiz"):
        build_request("start", "quizz", "cli")
    with pytest.raises(ConfigError, match="takes no activity"):
        build_request("pause", "quiz", "cli")
    with pytest.raises(ConfigError, match=r"^--by: "):
        build_request("cancel", None, "a/b")


def test_every_wrong_setting_is_listed_with_the_name_it_probably_meant(tmp_path: Path) -> None:
    config = tmp_path / "dms.toml"
    config.write_text('robot_idd = "x"\n[controler]\n[frames]\nface_live = 3\n')
    with pytest.raises(ConfigError) as caught:
        load_config(config, use_environment=False)
    line = str(caught.value)
    assert line.startswith(f"{config}: ") and "\n" not in line
    for wrong, meant in (
        ("robot_idd", "robot_id"),
        ("controler", "controller"),
        ("frames.face_live", "face_live_s"),
    ):
        assert f"{wrong}: Extra inputs are not permitted (did you mean {meant}?)" in line


def test_a_foxglove_websocket_v1_handshake_is_offered_and_answered_under_both_names() -> None:
    head = (
        b"GET / HTTP/1.1\r\nHost: x\r\nSec-WebSocket-Protocol: foxglove.websocket.v1\r\n"
        b"Sec-WebSocket-Key: abc\r\n\r\n"
    )
    sent, legacy = negotiate(head)
    assert legacy and b"Sec-WebSocket-Protocol: foxglove.sdk.v1\r\n" in sent
    assert b"foxglove.websocket.v1" not in sent and b"Sec-WebSocket-Key: abc" in sent
    answer = b"HTTP/1.1 101 Switching Protocols\r\nsec-websocket-protocol: foxglove.sdk.v1\r\n\r\n"
    assert b"sec-websocket-protocol: foxglove.websocket.v1" in rename_back(answer)
    both = head.replace(b"foxglove.websocket.v1", b"foxglove.sdk.v1, foxglove.websocket.v1")
    assert negotiate(both) == (both, False)


unit = st.floats(-1.0, 1.0, allow_nan=False)
angle = st.floats(-2 * math.pi, 2 * math.pi, allow_nan=False)


@given(st.tuples(unit, unit, unit, unit).filter(lambda q: sum(v * v for v in q) > 1e-6))
def test_a_quaternion_rotates_as_scipy_says(quaternion: tuple[float, ...]) -> None:
    expected = Rotation.from_quat(list(quaternion)).as_matrix()
    assert np.allclose(pose(quaternion=quaternion)[:3, :3], expected, atol=1e-12)


@given(st.tuples(angle, angle, angle))
def test_roll_pitch_yaw_rotate_as_scipy_says(rpy: tuple[float, float, float]) -> None:
    expected = Rotation.from_euler("xyz", list(rpy)).as_matrix()
    assert np.allclose(pose(rpy=rpy)[:3, :3], expected, atol=1e-12)


def test_a_quaternion_without_direction_is_refused() -> None:
    with pytest.raises(ValueError, match="not a rotation"):
        pose(quaternion=(0.0, 0.0, 0.0, 0.0))


def test_the_simulators_extras_are_looked_for_without_importing_them(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    assert missing_sim_extras() == []
    monkeypatch.setitem(sys.modules, "scipy", None)  # as if it were not installed
    assert missing_sim_extras() == ["scipy"]
    assert SIM_EXTRAS == ("matplotlib", "scipy")


def test_a_recording_is_named_as_ros2_bag_names_one() -> None:
    from datetime import datetime

    assert default_name("mini", datetime(2026, 11, 27, 9, 5, 3)) == Path(
        "dms_mini_20261127-090503.mcap"
    )
