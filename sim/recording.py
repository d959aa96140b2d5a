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
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from mcap.exceptions import McapError
from mcap.records import Attachment, Channel, Footer, Message, Metadata
from mcap.writer import CompressionType, Writer

from dms.kernel import keys
from dms.kernel.messages import SCHEMAS, json_schema
from sim.errors import RecordingError
from sim.mcap_read import check_chunk_size, mcap_records, read_summary

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


CONFIG_FIELDS: dict[str, Any] = {
    "robot_id": "",
    "seed": None,
    "versions": {},
    "settings": {},
    "files": [],
}
"""The fields of the stored configuration, and what stands in for one that is missing."""


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
    stored: tuple[str, ...] = ()
    """The names of the files the recorder stored, in its order."""
    missing: tuple[str, ...] = ()
    """The fields that were missing or could not be read (a file written by another
    version, or edited): the defaults stood in for them (:attr:`warnings` says so)."""

    @property
    def warnings(self) -> list[str]:
        """One line per missing field, naming it."""
        return [
            f"the stored configuration lacks {name!r} (or it cannot be read): "
            f"{'the defaults stand in for it' if name == 'settings' else 'left out'}"
            for name in self.missing
        ]

    @classmethod
    def parse(
        cls, metadata: dict[str, str] | None, attachments: dict[str, bytes]
    ) -> RecordedConfig | None:
        if metadata is None:
            return None
        values: dict[str, Any] = {}
        missing: list[str] = []
        for name, default in CONFIG_FIELDS.items():
            readable, value = _config_field(name, metadata.get(name))
            if not readable:
                missing.append(name)
                value = default
            values[name] = value
        index = [item for item in values["files"] if isinstance(item, dict)]
        names = [str(item.get("name")) for item in index]
        return cls(
            robot_id=values["robot_id"],
            seed=values["seed"],
            versions={str(k): str(v) for k, v in values["versions"].items()},
            settings=values["settings"],
            files={name: attachments[name] for name in names if name in attachments},
            sources={
                str(item.get("name")): str(item.get("path")) for item in index if item.get("path")
            },
            stored=tuple(names),
            missing=tuple(missing),
        )


def _config_field(name: str, text: str | None) -> tuple[bool, Any]:
    """(whether it could be read, its value) of one field of the stored configuration."""
    if text is None:
        return False, None
    if name == "robot_id":
        return True, text
    try:
        value = json.loads(text)
    except ValueError:
        return False, None
    if name == "seed":  # null: the recorded daemon ran without one
        return value is None or (isinstance(value, int) and not isinstance(value, bool)), value
    return isinstance(value, type(CONFIG_FIELDS[name])), value


class RecordingReader:
    """Reads a recording's messages one at a time, in file order, with bounded memory
    (:mod:`sim.mcap_read`): ``dms record play`` publishes them as they come. What it
    met on the way (the robot, the metadata, where a cut file ended) is kept on it."""

    def __init__(self, path: Path, keep_attachments: bool = True) -> None:
        self.path = path
        self.keep_attachments = keep_attachments
        self.robot_id: str | None = None
        self.truncated: str | None = None
        """None for a complete file, once read; else where and why it ended."""
        self.bad_messages = 0
        self.metadata: dict[str, dict[str, str]] = {}
        self.attachments: dict[str, bytes] = {}
        self.attachment_sizes: dict[str, int] = {}

    def messages(self) -> Iterator[RecordedMessage]:
        """Each complete message of the file; a truncated file yields what it holds.
        RecordingError: not an MCAP file, or a record over a bound."""
        path = self.path
        try:
            stream = path.open("rb")
        except OSError as error:
            raise RecordingError(f"{path}: cannot read: {error.strerror or error}") from None
        channels: dict[int, str] = {}
        count, last = 0, None
        self.truncated, complete = None, False
        with stream:
            try:
                for record in mcap_records(stream, str(path)):
                    if isinstance(record, Metadata):
                        self.metadata.setdefault(record.name, dict(record.metadata))
                    elif isinstance(record, Attachment):
                        self.attachment_sizes.setdefault(record.name, len(record.data))
                        if self.keep_attachments:
                            self.attachments.setdefault(record.name, bytes(record.data))
                    elif isinstance(record, Channel):
                        channels[record.id] = record.topic
                        if self.robot_id is None and record.topic.startswith("robots/"):
                            self.robot_id = record.topic.split("/")[1]
                    elif isinstance(record, Message):
                        message = self._message(record, channels.get(record.channel_id))
                        if message is not None:
                            count, last = count + 1, message.log_time_ns
                            yield message
                    elif isinstance(record, Footer):
                        complete = True
            except (McapError, struct.error, EOFError, ValueError, MemoryError) as error:
                when = f" after the message at {_iso_ns(last)}" if last is not None else ""
                reason = str(error) or "end of file"
                self.truncated = (
                    f"the file ({path.stat().st_size} bytes) ends inside a record{when}: "
                    f"read {count} messages ({reason})"
                )
            if self.truncated is None and not complete:
                self.truncated = f"the file ends without its footer: read {count} messages"
        if not count and self.truncated is not None and not channels:
            if self.metadata:  # an MCAP file that was cut before its first message
                raise RecordingError(f"{path}: cut before its first message ({self.truncated})")
            raise RecordingError(f"{path}: not an MCAP recording ({self.truncated})")

    def _message(self, record: Message, topic: str | None) -> RecordedMessage | None:
        try:
            payload = json.loads(record.data)
        except (ValueError, UnicodeDecodeError):
            payload = None
            topic = None
        if topic is None:
            self.bad_messages += 1
            return None
        key = topic.split("/", 2)[2] if topic.count("/") >= 2 else topic
        return RecordedMessage(key, record.log_time, payload)


def read_recording(path: Path) -> Recording:
    """Read every complete message of ``path``; a truncated file yields what it holds.
    ``dms sim replay`` needs them all at once; ``dms record play`` streams them."""
    reader = RecordingReader(path)
    messages = sorted(reader.messages(), key=lambda message: message.log_time_ns)
    return Recording(
        reader.robot_id,
        messages,
        reader.truncated,
        reader.bad_messages,
        reader.metadata,
        reader.attachments,
    )


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
    messages: Callable[[], Iterable[RecordedMessage]],
    publish: Callable[[RecordedMessage], None],
    stop: threading.Event,
    rate: float = 1.0,
    loop: bool = False,
    clock: Callable[[], float] = time.monotonic,
) -> int:
    """Publish the messages ``messages()`` yields at their recorded pace (``rate`` times
    faster), again from the start (a new ``messages()``) when ``loop``, until the last
    one or ``stop``; returns how many were published. They are read as they are played
    (:class:`RecordingReader`), so a long recording takes no more memory than a short one.

    Each message is due at the start plus its recorded offset, a deadline on ``clock``
    (not a sleep after each one: a slow publish does not delay the rest); one recorded
    before the previous is due at once."""
    if rate <= 0:
        raise ValueError("rate must be > 0")
    published = 0
    while not stop.is_set():
        first_ns: int | None = None
        start = clock()
        for message in messages():
            if first_ns is None:
                first_ns, start = message.log_time_ns, clock()
            due = start + (message.log_time_ns - first_ns) / 1e9 / rate
            wait = due - clock()
            if wait > 0 and stop.wait(wait):
                return published
            if stop.is_set():
                return published
            publish(message)
            published += 1
        if not loop or first_ns is None:
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
    with path.open("rb") as stream:
        try:
            summary, metadata = read_summary(stream, str(path))
        except (McapError, struct.error, EOFError, ValueError, OSError):
            summary = None  # a file cut short: read as far as it goes
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
    for chunk in chunks:  # what the summary says; reading checks what the chunks hold
        check_chunk_size(chunk.uncompressed_size, str(path))
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
    reader = RecordingReader(path, keep_attachments=False)
    topics: dict[str, int] = {}
    count, start_ns, end_ns = 0, None, None
    for message in reader.messages():
        topics[message.key] = topics.get(message.key, 0) + 1
        count += 1
        start_ns = min(start_ns or message.log_time_ns, message.log_time_ns)
        end_ns = max(end_ns or message.log_time_ns, message.log_time_ns)
    robot = reader.robot_id or "?"
    info.update(
        {
            "complete": False,
            "truncated": reader.truncated,
            "messages": count,
            "start_ns": start_ns,
            "end_ns": end_ns,
            "topics": [
                {"topic": f"robots/{robot}/{key}", "count": count, "schema": None}
                for key, count in sorted(topics.items())
            ],
            "attachments": [
                {"name": name, "bytes": size} for name, size in reader.attachment_sizes.items()
            ],
        }
    )
    info["config"] = _config_info(reader.metadata.get(CONFIG_METADATA))
    return info


def _config_info(metadata: dict[str, str] | None) -> dict[str, Any] | None:
    config = RecordedConfig.parse(metadata, {})
    if config is None:
        return None
    return {
        "robot_id": config.robot_id,
        "seed": config.seed,
        "versions": config.versions,
        "files": list(config.stored),
        "warnings": config.warnings,
    }
