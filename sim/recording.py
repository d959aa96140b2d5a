"""MCAP recordings of one robot's key space, and reading them back.

:class:`McapRecorder` writes every sample under ``robots/<id>/**`` as a JSON message
on a channel named by its key, with the JSON Schema of the message when the key is
one of docs/contract.md's (so Foxglove shows typed fields). Chunks are small and
zstd-compressed and the file is flushed after each chunk: a recording cut short (the
recorder killed, the disk full, a copy interrupted) loses at most its last chunk, and
:func:`read_recording` reads every complete record before the cut and says where it
ended, and :func:`play` publishes what it read at the recorded pace (``dms record play``).

What the replay needs besides the messages is stored once, when the daemon answers
``dms/config`` (:meth:`McapRecorder.add_config`): the seed, the versions and the
settings as MCAP metadata ``dms-config``, and the rule, behavior and content files in
force as attachments (``rules/0/decisions.dmsl``, ``behaviors/quiz.yaml``,
``content/quiz.yaml``). ``dms sim replay FILE`` then needs no flags.
"""

from __future__ import annotations

import hashlib
import json
import struct
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.records import Attachment, Channel, Message, Metadata, Schema
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

CHUNK_SIZE = 16 * 1024
"""Small chunks: a recorder killed outright loses only its open chunk, the last 8 s or so
(a daemon publishes about 2 KB a second), yet zstd shrinks a day's recording about 4.5
times (8 KB chunks: 3.8, 64 KB: 7)."""

CONFIG_METADATA = "dms-config"
"""The MCAP metadata record holding the recorded daemon's seed, versions and settings."""


@dataclass
class RecordStats:
    """What a recording holds."""

    messages: int = 0
    by_key: dict[str, int] = field(default_factory=dict)
    skipped: int = 0
    """Samples that were not JSON (recorded nowhere; counted here)."""
    configured: bool = False
    """The daemon's configuration (seed, settings, files) is stored."""


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
        self._writer = Writer(stream, chunk_size=CHUNK_SIZE, compression=CompressionType.ZSTD)
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

    def add_config(self, snapshot: dict[str, Any], log_time_ns: int) -> bool:
        """Store the daemon's answer to ``dms/config`` (see the module docstring); only the
        first one is kept. False when it was not stored (closed, already stored, or not a
        snapshot)."""
        files = snapshot.get("files")
        if not isinstance(files, list) or not isinstance(snapshot.get("settings"), dict):
            return False
        index: list[dict[str, Any]] = []
        with self._lock:
            if self._closed or self.stats.configured:
                return False
            for item in files:
                if not isinstance(item, dict):
                    continue
                name, text = str(item.get("name", "")), item.get("text")
                if not name or not isinstance(text, str):
                    continue
                data = text.encode("utf-8")
                media = "application/yaml" if name.endswith((".yaml", ".yml")) else "text/plain"
                self._writer.add_attachment(
                    create_time=log_time_ns,
                    log_time=log_time_ns,
                    name=name,
                    media_type=media,
                    data=data,
                )
                digest = hashlib.sha256(data).hexdigest()
                index.append({"name": name, "path": item.get("path"), "sha256": digest})
            self._writer.add_metadata(
                CONFIG_METADATA,
                {
                    "robot_id": str(snapshot.get("robot_id", self.robot_id)),
                    "seed": json.dumps(snapshot.get("seed")),
                    "versions": json.dumps(snapshot.get("versions", {})),
                    "settings": json.dumps(snapshot["settings"]),
                    "files": json.dumps(index),
                },
            )
            self.stats.configured = True
            if self._file is not None:
                self._file.flush()
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
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    attachments: dict[str, bytes] = field(default_factory=dict)

    @property
    def config(self) -> RecordedConfig | None:
        """The recorded daemon's configuration, when the recorder could store it."""
        return RecordedConfig.parse(self.metadata.get(CONFIG_METADATA), self.attachments)


@dataclass(frozen=True)
class RecordedConfig:
    """What :meth:`McapRecorder.add_config` stored: enough to replay without flags."""

    robot_id: str
    seed: int | None
    versions: dict[str, str]
    settings: dict[str, Any]
    files: dict[str, bytes]
    """Attachment name (``rules/0/decisions.dmsl``, ``behaviors/quiz.yaml``) to content."""
    sources: dict[str, str]
    """Attachment name to the path it had on the recorded machine."""

    @classmethod
    def parse(
        cls, metadata: dict[str, str] | None, attachments: dict[str, bytes]
    ) -> RecordedConfig | None:
        if metadata is None:
            return None
        try:
            seed = json.loads(metadata.get("seed", "null"))
            versions = json.loads(metadata.get("versions", "{}"))
            settings = json.loads(metadata["settings"])
            index = json.loads(metadata.get("files", "[]"))
        except (KeyError, ValueError) as error:
            raise RecordingError(f"the stored configuration cannot be read: {error}") from None
        names = [str(item.get("name")) for item in index if isinstance(item, dict)]
        return cls(
            robot_id=metadata.get("robot_id", ""),
            seed=seed if isinstance(seed, int) else None,
            versions={str(k): str(v) for k, v in versions.items()},
            settings=settings,
            files={name: attachments[name] for name in names if name in attachments},
            sources={
                str(item.get("name")): str(item.get("path"))
                for item in index
                if isinstance(item, dict) and item.get("path")
            },
        )


def read_recording(path: Path) -> Recording:
    """Read every complete message of ``path``; a truncated file yields what it holds."""
    try:
        stream = path.open("rb")
    except OSError as error:
        raise RecordingError(f"{path}: cannot read: {error.strerror or error}") from None
    channels: dict[int, str] = {}
    robot_id: str | None = None
    messages: list[RecordedMessage] = []
    metadata: dict[str, dict[str, str]] = {}
    attachments: dict[str, bytes] = {}
    bad = 0
    truncated: str | None = None
    complete = False
    with stream:
        reader = StreamReader(stream, record_size_limit=256 * 1024 * 1024)
        try:
            for record in reader.records:
                if isinstance(record, Schema):
                    continue
                if isinstance(record, Metadata):
                    metadata.setdefault(record.name, dict(record.metadata))
                    continue
                if isinstance(record, Attachment):
                    attachments.setdefault(record.name, bytes(record.data))
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
        if metadata:  # an MCAP file that was cut before its first message
            raise RecordingError(f"{path}: cut before its first message ({truncated})")
        raise RecordingError(f"{path}: not an MCAP recording ({truncated})")
    messages.sort(key=lambda message: message.log_time_ns)
    return Recording(robot_id, messages, truncated, bad, metadata, attachments)


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
    key_exprs: Sequence[str] = (),
) -> RecordStats:
    """Subscribe to ``key_exprs`` (by default the robot's whole key space) and record
    until ``stop`` or ``duration_s``."""

    def on_sample(topic: str, payload: bytes) -> None:
        recorder.write(topic, payload, clock_ns())

    for key_expr in key_exprs or [f"robots/{recorder.robot_id}/**"]:
        subscribe(key_expr, on_sample)
    stop.wait(duration_s)
    recorder.close()
    return recorder.stats


def play(
    messages: Sequence[RecordedMessage],
    publish: Callable[[RecordedMessage], None],
    stop: threading.Event,
    rate: float = 1.0,
    loop: bool = False,
    clock: Callable[[], float] = time.monotonic,
) -> int:
    """Publish ``messages`` at their recorded pace (``rate`` times faster), again from the
    start when ``loop``, until the last one or ``stop``; returns how many were published.

    Each message is due at the start plus its recorded offset, a deadline on ``clock``
    (not a sleep after each one: a slow publish does not delay the rest)."""
    if rate <= 0:
        raise ValueError("rate must be > 0")
    published = 0
    while messages and not stop.is_set():
        first_ns = messages[0].log_time_ns
        start = clock()
        for message in messages:
            due = start + (message.log_time_ns - first_ns) / 1e9 / rate
            wait = due - clock()
            if wait > 0 and stop.wait(wait):
                return published
            if stop.is_set():
                return published
            publish(message)
            published += 1
        if not loop:
            break
    return published


def recording_info(path: Path) -> dict[str, Any]:
    """What ``dms record info`` prints (as ``ros2 bag info`` does): size, duration,
    messages per topic with its schema, chunks and their compression, the stored
    configuration. A complete file is described from its summary section; a truncated
    one is read as far as it goes."""
    try:
        size = path.stat().st_size
    except OSError as error:
        raise RecordingError(f"{path}: cannot read: {error.strerror or error}") from None
    info: dict[str, Any] = {"file": str(path), "bytes": size}
    summary = None
    with path.open("rb") as stream:
        try:
            reader = make_reader(stream)
            summary = reader.get_summary()
            metadata = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
        except (McapError, struct.error, EOFError, ValueError):
            summary = None
    if summary is None or summary.statistics is None:
        return _info_by_reading(path, info)
    stats = summary.statistics
    schema_of = {
        channel.topic: summary.schemas[channel.schema_id].name
        for channel in summary.channels.values()
        if channel.schema_id in summary.schemas
    }
    topics = {
        summary.channels[cid].topic: count for cid, count in stats.channel_message_counts.items()
    }
    chunks = summary.chunk_indexes
    info.update(
        {
            "complete": True,
            "messages": stats.message_count,
            "start_ns": stats.message_start_time if stats.message_count else None,
            "end_ns": stats.message_end_time if stats.message_count else None,
            "topics": [
                {"topic": topic, "count": count, "schema": schema_of.get(topic)}
                for topic, count in sorted(topics.items())
            ],
            "chunks": len(chunks),
            "compression": sorted({chunk.compression or "none" for chunk in chunks}),
            "uncompressed_bytes": sum(chunk.uncompressed_size for chunk in chunks),
            "compressed_bytes": sum(chunk.compressed_size for chunk in chunks),
            "attachments": [
                {"name": a.name, "bytes": a.data_size} for a in summary.attachment_indexes
            ],
        }
    )
    info["config"] = _config_info(metadata.get(CONFIG_METADATA))
    return info


def _info_by_reading(path: Path, info: dict[str, Any]) -> dict[str, Any]:
    recording = read_recording(path)
    topics: dict[str, int] = {}
    for message in recording.messages:
        topics[message.key] = topics.get(message.key, 0) + 1
    robot = recording.robot_id or "?"
    times = [m.log_time_ns for m in recording.messages]
    info.update(
        {
            "complete": False,
            "truncated": recording.truncated,
            "messages": len(recording.messages),
            "start_ns": min(times) if times else None,
            "end_ns": max(times) if times else None,
            "topics": [
                {"topic": f"robots/{robot}/{key}", "count": count, "schema": None}
                for key, count in sorted(topics.items())
            ],
            "attachments": [
                {"name": name, "bytes": len(data)} for name, data in recording.attachments.items()
            ],
        }
    )
    info["config"] = _config_info(recording.metadata.get(CONFIG_METADATA))
    return info


def _config_info(metadata: dict[str, str] | None) -> dict[str, Any] | None:
    if metadata is None:
        return None
    config = RecordedConfig.parse(metadata, {})
    assert config is not None
    files = json.loads(metadata.get("files", "[]"))
    return {
        "robot_id": config.robot_id,
        "seed": config.seed,
        "versions": config.versions,
        "files": [item.get("name") for item in files if isinstance(item, dict)],
    }
