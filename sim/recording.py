"""MCAP recordings of one robot's key space, and reading them back.

:class:`McapRecorder` writes every sample under ``robots/<id>/**`` as a JSON message
on a channel named by its key, with the JSON Schema of the message when the key is
one of CONTRACT.md's (so Foxglove shows typed fields). Chunks are small and
uncompressed and the file is flushed after each message: a recording cut short (the
recorder killed, the disk full, a copy interrupted) loses at most its last chunk, and
:func:`read_recording` reads every complete record before the cut and says where it
ended.
"""

from __future__ import annotations

import json
import struct
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from mcap.exceptions import McapError
from mcap.records import Channel, Message, Schema
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, Writer

from dms.kernel import keys
from dms.kernel.messages import SCHEMAS, json_schema
from sim.errors import RecordingError

SCHEMA_BY_KEY: dict[str, str] = {
    keys.PERCEPTION_USER: "perception_user",
    keys.PERCEPTION_TOUCH: "perception_touch",
    keys.PERCEPTION_SPEECH: "perception_speech",
    keys.PERCEPTION_SCREEN: "perception_screen",
    keys.PARAMS_ROBOT: "params",
    keys.PARAMS_ENV: "params",
    keys.REQUEST: "request",
    keys.ROBOT_FEEDBACK: "robot_feedback",
    keys.ROBOT_COMMAND: "robot_command",
    keys.DMS_ERRORS: "dms_errors",
    keys.DMS_STATE: "dms_state",
    keys.DMS_DECISION: "dms_decision",
}
"""The schema (a name in :data:`dms.kernel.messages.SCHEMAS`) of each contract key."""

CHUNK_SIZE = 8 * 1024
"""Small chunks: a recorder killed outright loses only the last few seconds."""


@dataclass
class RecordStats:
    """What a recording holds."""

    messages: int = 0
    by_key: dict[str, int] = field(default_factory=dict)
    skipped: int = 0
    """Samples that were not JSON (recorded nowhere; counted here)."""


class McapRecorder:
    """Writes samples of one robot into an MCAP file; safe to call from Zenoh threads."""

    def __init__(
        self,
        out: Path | IO[bytes],
        robot_id: str,
        on_written: Callable[[str, bytes], None] | None = None,
    ) -> None:
        """``on_written(key, payload)`` is called after each message is recorded."""
        self.robot_id = robot_id
        self._on_written = on_written
        self._file: IO[bytes] | None = None
        if isinstance(out, Path):
            try:
                self._file = out.open("wb")
            except OSError as error:
                raise RecordingError(f"{out}: cannot write: {error.strerror or error}") from None
            stream: IO[bytes] = self._file
        else:
            stream = out
        self._writer = Writer(stream, chunk_size=CHUNK_SIZE, compression=CompressionType.NONE)
        self._writer.start(profile="", library="dms record")
        self._writer.add_metadata("dms", {"robot_id": robot_id, "encoding": "json"})
        self._lock = threading.Lock()
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}
        self._sequence = 0
        self._closed = False
        self.stats = RecordStats()

    def _channel(self, topic: str, key: str) -> int:
        channel = self._channels.get(topic)
        if channel is not None:
            return channel
        schema_name = SCHEMA_BY_KEY.get(key)
        schema_id = 0
        if schema_name is not None:
            schema_id = self._schemas.get(schema_name, 0)
            if not schema_id:
                schema = json_schema(SCHEMAS[schema_name])
                schema_id = self._writer.register_schema(
                    name=schema.get("title", schema_name),
                    encoding="jsonschema",
                    data=json.dumps(schema).encode(),
                )
                self._schemas[schema_name] = schema_id
        channel = self._writer.register_channel(
            topic=topic, message_encoding="json", schema_id=schema_id
        )
        self._channels[topic] = channel
        return channel

    def write(self, topic: str, payload: bytes, log_time_ns: int) -> bool:
        """Record one sample on ``topic`` (a full key); False if it was not JSON."""
        key = keys.relative(self.robot_id, topic) or topic
        try:
            json.loads(payload)
        except (ValueError, UnicodeDecodeError):
            with self._lock:
                self.stats.skipped += 1
            return False
        with self._lock:
            if self._closed:
                return False
            channel = self._channel(topic, key)
            self._writer.add_message(
                channel_id=channel,
                log_time=log_time_ns,
                publish_time=log_time_ns,
                data=payload,
                sequence=self._sequence,
            )
            self._sequence += 1
            if self._file is not None:
                self._file.flush()
            self.stats.messages += 1
            self.stats.by_key[key] = self.stats.by_key.get(key, 0) + 1
        if self._on_written is not None:
            self._on_written(key, payload)
        return True

    def close(self) -> None:
        """Write the summary (index, statistics) and close the file."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            self._writer.finish()  # type: ignore[no-untyped-call]
            if self._file is not None:
                self._file.close()


@dataclass(frozen=True, slots=True)
class RecordedMessage:
    """One message read back: its key (relative to the robot), time and JSON payload."""

    key: str
    log_time_ns: int
    payload: Any


@dataclass
class Recording:
    """The messages of a recording in log order, and where reading stopped if cut short."""

    robot_id: str | None
    messages: list[RecordedMessage]
    truncated: str | None = None
    """None for a complete file; else where and why it ended."""
    bad_messages: int = 0


def read_recording(path: Path) -> Recording:
    """Read every complete message of ``path``; a truncated file yields what it holds."""
    try:
        stream = path.open("rb")
    except OSError as error:
        raise RecordingError(f"{path}: cannot read: {error.strerror or error}") from None
    channels: dict[int, str] = {}
    robot_id: str | None = None
    messages: list[RecordedMessage] = []
    bad = 0
    truncated: str | None = None
    complete = False
    with stream:
        reader = StreamReader(stream, record_size_limit=256 * 1024 * 1024)
        try:
            for record in reader.records:
                if isinstance(record, Schema):
                    continue
                if isinstance(record, Channel):
                    channels[record.id] = record.topic
                    if robot_id is None and record.topic.startswith("robots/"):
                        robot_id = record.topic.split("/")[1]
                elif isinstance(record, Message):
                    topic = channels.get(record.channel_id)
                    try:
                        payload = json.loads(record.data)
                    except (ValueError, UnicodeDecodeError):
                        bad += 1
                        continue
                    if topic is None:
                        bad += 1
                        continue
                    key = topic.split("/", 2)[2] if topic.count("/") >= 2 else topic
                    messages.append(RecordedMessage(key, record.log_time, payload))
                elif type(record).__name__ == "Footer":
                    complete = True
        except (McapError, struct.error, EOFError, ValueError, MemoryError) as error:
            last = messages[-1].log_time_ns if messages else None
            when = f" after the message at {_iso_ns(last)}" if last is not None else ""
            reason = str(error) or "end of file"
            truncated = (
                f"the file ({path.stat().st_size} bytes) ends inside a record{when}: "
                f"read {len(messages)} messages ({reason})"
            )
        if truncated is None and not complete:
            truncated = f"the file ends without its footer: read {len(messages)} messages"
    if not messages and truncated is not None and not channels:
        raise RecordingError(f"{path}: not an MCAP recording ({truncated})")
    messages.sort(key=lambda message: message.log_time_ns)
    return Recording(robot_id, messages, truncated, bad)


def _iso_ns(ns: int) -> str:
    from datetime import UTC, datetime

    from dms.kernel.clock import iso

    return iso(datetime.fromtimestamp(ns / 1e9, UTC))


def record_until(
    recorder: McapRecorder,
    subscribe: Callable[[str, Callable[[str, bytes], None]], None],
    clock_ns: Callable[[], int],
    stop: threading.Event,
    duration_s: float | None,
) -> RecordStats:
    """Subscribe to the robot's key space and record until ``stop`` or ``duration_s``."""

    def on_sample(topic: str, payload: bytes) -> None:
        recorder.write(topic, payload, clock_ns())

    subscribe(f"robots/{recorder.robot_id}/**", on_sample)
    stop.wait(duration_s)
    recorder.close()
    return recorder.stats
