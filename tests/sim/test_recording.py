"""MCAP recordings: JSON messages with their schemas, and truncated files read as far as they go."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from mcap.reader import make_reader

from sim.errors import RecordingError
from sim.recording import McapRecorder, read_recording

BASE_NS = 1_795_000_000_000_000_000


def _decision(tick: int) -> bytes:
    return json.dumps(
        {
            "tick": tick,
            "time": "2026-11-22T10:00:00.000Z",
            "action": "start",
            "activity": "quiz",
            "manager": "entertainment",
            "reason": "preference",
            "chosen_by": "robot",
            "detail": None,
        }
    ).encode()


def _record(path: Path, count: int) -> None:
    recorder = McapRecorder(path, "mini")
    for i in range(count):
        user = {"present": True, "user_id": "alice", "ready": True, "engagement": None}
        assert recorder.write(
            "robots/mini/perception/user", json.dumps(user).encode(), BASE_NS + i * 500_000_000
        )
        assert recorder.write("robots/mini/dms/decision", _decision(i), BASE_NS + i * 500_000_001)
    assert not recorder.write("robots/mini/perception/user", b"not json", BASE_NS)
    recorder.close()
    assert recorder.stats.messages == 2 * count and recorder.stats.skipped == 1


def test_messages_carry_json_schemas(tmp_path: Path) -> None:
    path = tmp_path / "r.mcap"
    _record(path, 10)
    with path.open("rb") as stream:
        reader = make_reader(stream)
        summary = reader.get_summary()
        assert summary is not None
        schemas = {schema.name: schema for schema in summary.schemas.values()}
        assert {"UserPerception", "Decision"} <= set(schemas)
        for schema in schemas.values():
            assert schema.encoding == "jsonschema"
            assert json.loads(schema.data)["type"] == "object"
        topics = {channel.topic: channel for channel in summary.channels.values()}
        assert set(topics) == {"robots/mini/perception/user", "robots/mini/dms/decision"}
        assert all(channel.message_encoding == "json" for channel in topics.values())
        assert summary.statistics is not None and summary.statistics.message_count == 20


def test_reads_back_in_order(tmp_path: Path) -> None:
    path = tmp_path / "r.mcap"
    _record(path, 50)
    recording = read_recording(path)
    assert recording.truncated is None and recording.robot_id == "mini"
    assert len(recording.messages) == 100
    assert [m.key for m in recording.messages[:2]] == ["perception/user", "dms/decision"]
    times = [m.log_time_ns for m in recording.messages]
    assert times == sorted(times)
    assert recording.messages[1].payload["tick"] == 0


def test_truncated_file_gives_what_it_holds(tmp_path: Path) -> None:
    path = tmp_path / "r.mcap"
    _record(path, 3000)
    data = path.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) // 2])
    recording = read_recording(cut)
    assert recording.truncated is not None
    assert "ends inside a record" in recording.truncated
    assert 1000 < len(recording.messages) < 6000
    ticks = [m.payload["tick"] for m in recording.messages if m.key == "dms/decision"]
    assert ticks == list(range(len(ticks)))  # a prefix, nothing made up


def test_not_an_mcap_file(tmp_path: Path) -> None:
    path = tmp_path / "x.mcap"
    path.write_bytes(b"hello")
    with pytest.raises(RecordingError, match="not an MCAP recording"):
        read_recording(path)
    with pytest.raises(RecordingError, match="cannot read"):
        read_recording(tmp_path / "absent.mcap")
