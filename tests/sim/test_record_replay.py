"""Record a live daemon over real Zenoh into MCAP, then replay it on the virtual clock.

The daemon runs as a subprocess on a free loopback port (multicast scouting off);
every wait is for a message, with a deadline.
"""

from __future__ import annotations

import json
import threading
import time
from pathlib import Path

import pytest

from dms.bus import ZenohClient, make_config
from dms.config import load_config
from sim.recording import McapRecorder, read_recording, record_until
from sim.replay import replay
from tests.integration.harness import Collector, put, running_daemon

pytestmark = pytest.mark.integration


def test_record_then_replay_round_trip(tmp_path: Path) -> None:
    out = tmp_path / "session.mcap"
    # The user takes the initiative for sure: a random draw made before the recording
    # began could otherwise turn out differently in the replay.
    with running_daemon(tmp_path, "user_initiative = { unknown = 1.0 }\n") as (daemon, session):
        seen_state = threading.Event()
        seen_left = threading.Event()

        left_tick: list[int] = []

        def on_written(key: str, payload: bytes) -> None:
            if key == "dms/state":
                seen_state.set()
                if left_tick and json.loads(payload)["tick"] == left_tick[0]:
                    seen_left.set()  # every decision of that tick is recorded
            if key == "dms/decision" and b"user_left" in payload:
                left_tick.append(json.loads(payload)["tick"])

        client = ZenohClient("mini", make_config(connect=[f"tcp/127.0.0.1:{daemon.port}"]))
        recorder = McapRecorder(out, "mini", on_written=on_written)
        stop = threading.Event()
        stats_box: list[object] = []
        thread = threading.Thread(
            target=lambda: stats_box.append(
                record_until(recorder, client.subscribe_raw, time.time_ns, stop, None)
            )
        )
        thread.start()
        try:
            assert seen_state.wait(10.0), "the recorder never saw the daemon's state"
            decisions = Collector(session, "robots/mini/dms/decision")
            put(session, "perception/user", {"present": True, "user_id": "alice", "ready": True})
            decisions.wait_for(lambda d: d["reason"] == "user_arrived")
            put(session, "request", {"action": "start", "activity": "jokes", "by": "test"})
            decisions.wait_for(lambda d: d["action"] == "start" and d["activity"] == "jokes")
            put(session, "perception/user", {"present": False, "user_id": None, "ready": False})
            decisions.wait_for(lambda d: d["reason"] == "user_left")
            assert seen_left.wait(10.0), "the recorder never got the last tick"
        finally:
            stop.set()
            thread.join(10.0)
            client.close()
        assert daemon.terminate() == 0
    recording = read_recording(out)
    assert recording.truncated is None
    keys = {m.key for m in recording.messages}
    assert {"perception/user", "request", "dms/state", "dms/decision", "robot/command"} <= keys

    settings = load_config(daemon.config).model_copy(update={"db": None})
    report = replay(out, seed=settings.seed or 0, settings=settings)
    assert report.inputs >= 3
    recorded = [(d.action, d.activity, d.reason) for d in report.recorded]
    replayed = [(d.action, d.activity, d.reason) for d in report.replayed]
    assert ("start", "jokes", "user_request") in recorded
    assert ("start", "jokes", "user_request") in replayed
    assert report.same, report.text()

    # Cut the file: the replay runs what it holds and says where it ended.
    data = out.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: int(len(data) * 0.6)])
    partial = replay(cut, seed=settings.seed or 0, settings=settings)
    assert partial.truncated is not None
    assert partial.span_s <= report.span_s
