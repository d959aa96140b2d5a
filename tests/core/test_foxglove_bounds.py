"""``dms foxglove`` stays bounded whatever the bus carries: at most ``max_channels``
channels (the key seen longest ago is closed) and no sample over ``max_message_bytes``."""

from __future__ import annotations

import json
from collections.abc import Iterator

import pytest

from dms.foxglove_bridge import FoxgloveBridge


@pytest.fixture
def bridge() -> Iterator[FoxgloveBridge]:
    bridge = FoxgloveBridge(port=0, max_channels=4, max_message_bytes=1000)
    try:
        yield bridge
    finally:
        bridge.stop()


def test_made_up_keys_keep_at_most_the_bound_of_channels(bridge: FoxgloveBridge) -> None:
    sample = json.dumps({"n": 1}).encode()
    for index in range(1000):
        bridge.on_sample(f"robots/mini/made/up/{index}", sample)
    assert bridge.channels() == [f"robots/mini/made/up/{index}" for index in range(996, 1000)]
    assert bridge.closed == 996 and bridge.forwarded == 1000


def test_the_channel_seen_longest_ago_is_the_one_closed(bridge: FoxgloveBridge) -> None:
    sample = b'{"tick": 1}'
    for key in ("dms/state", "dms/decision", "robot/command", "dms/errors"):
        bridge.on_sample(f"robots/mini/{key}", sample)
    bridge.on_sample("robots/mini/dms/state", sample)  # the state speaks again
    bridge.on_sample("robots/mini/made/up", sample)
    assert "robots/mini/dms/state" in bridge.channels()
    assert "robots/mini/dms/decision" not in bridge.channels()
    bridge.on_sample("robots/mini/dms/decision", sample)  # speaks again: a new channel
    assert bridge.channels()[-1] == "robots/mini/dms/decision"


def test_a_sample_over_the_size_bound_is_dropped_unread(bridge: FoxgloveBridge) -> None:
    bridge.on_sample("robots/mini/dms/state", json.dumps({"x": "a" * 2000}).encode())
    bridge.on_sample("robots/mini/dms/state", b"[" * 400 + b"]" * 400)
    assert bridge.too_big == 1 and bridge.forwarded == 0 and bridge.channels() == []
    assert bridge.dropped == 1  # not an object


def test_the_outputs_of_a_robot_are_advertised_before_they_speak(bridge: FoxgloveBridge) -> None:
    bridge.advertise("mini")
    bridge.advertise("mini")  # once
    outputs = ["dms/state", "dms/decision", "dms/errors", "dms/behavior", "robot/command"]
    assert bridge.channels()[-4:] == [f"robots/mini/{key}" for key in outputs[1:]]
    assert bridge.forwarded == 0
