"""The profile store's writes on the background writer: what a write is, and how it is spooled.

The controller hands every store write to :meth:`StorageWriter.submit` (through
:class:`dms.profiles.ProfileService`), which never waits on the database. The queue, the
backoff, the spool, the quarantine and the reports are :class:`memory.writer.Writer`'s,
shared with the agenda; this module says what differs for the profile store: a write is
one store call (:class:`Write`), applied one at a time, its arguments spooled as JSON
(datetimes tagged), refused for good when the store says :class:`memory.errors.StoreRefused`,
reported under ``memory`` as "the storage writer".
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import Any, Literal, get_args

from memory.backlog import MEMORY_BOUND
from memory.watch import sqlite_file
from memory.writer import QUEUE_SIZE, RETRY_EVERY_S, Codec, Waiter, Writer
from memory.writer import WriterHealth as StorageHealth

__all__ = [
    "QUEUE_SIZE",
    "RETRY_EVERY_S",
    "STORE_OPS",
    "StorageHealth",
    "StorageWriter",
    "StoreOp",
    "Waiter",
    "Write",
    "sqlite_file",
]


def encode(value: Any) -> Any:
    """``value`` as JSON-able data: datetimes tagged, tuples as lists."""
    if isinstance(value, datetime):
        return {"$dt": value.isoformat()}
    if isinstance(value, list | tuple):
        return [encode(v) for v in value]
    if isinstance(value, dict):
        return {str(k): encode(v) for k, v in value.items()}
    if value is None or isinstance(value, str | int | float | bool):
        return value
    return {"$repr": repr(value)}  # not storable as given: replay will refuse it, and say so


def decode(value: Any) -> Any:
    """The inverse of :func:`encode` (tuples come back as lists)."""
    if isinstance(value, list):
        return [decode(v) for v in value]
    if isinstance(value, dict):
        if set(value) == {"$dt"}:
            return datetime.fromisoformat(value["$dt"])
        if set(value) == {"$repr"}:
            return str(value["$repr"])
        return {k: decode(v) for k, v in value.items()}
    return value


StoreOp = Literal[
    "get_or_create",
    "find",
    "last_run",
    "update",
    "start_session",
    "end_session",
    "record_activity",
    "record_feedback",
    "record_answer",
    "record_interaction",
    "record_initiative",
    "record_interactions",
]
"""What a :class:`Write` does: a :class:`memory.ProfileStore` method of that name (``find``
is ``get`` without the error). :class:`dms.profiles.ProfileService` makes each one from a
typed method; the name is what a spool file holds."""
STORE_OPS: frozenset[str] = frozenset(get_args(StoreOp))


@dataclass(frozen=True, slots=True)
class Write:
    """One store call, ``op(*args, **kwargs)``, as it is queued, spooled and replayed."""

    method: StoreOp
    args: tuple[Any, ...] = ()
    kwargs: dict[str, Any] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        return {"op": self.method, "args": encode(self.args), "kwargs": encode(self.kwargs)}

    @classmethod
    def from_json(cls, entry: dict[str, Any]) -> Write:
        op = entry["op"]
        if op not in STORE_OPS:
            raise ValueError(f"not a store write: {op!r:.60}")
        return cls(op, tuple(decode(entry["args"])), dict(decode(entry["kwargs"])))

    @staticmethod
    def readable(entry: dict[str, Any]) -> bool:
        """Whether a spooled entry is a write this dms makes: a known op, its arguments of
        the right types (others are set aside)."""
        return (
            entry.get("op") in STORE_OPS
            and isinstance(entry.get("args"), list)
            and isinstance(entry.get("kwargs"), dict)
        )


CODEC: Codec[Write] = Codec(Write.to_json, Write.from_json, Write.readable, lambda w: w.method)


class StorageWriter(Writer[Write]):
    """The profile store's writer: applies store calls in order off the caller's thread."""

    def __init__(
        self,
        apply: Callable[[Write], Any],
        spool_path: Path,
        quarantine_path: Path,
        report: Callable[[str, str], None],
        on_done: Callable[[Write, Any], None] = lambda write, result: None,
        *,
        threaded: bool = True,
        queue_size: int = QUEUE_SIZE,
        spool_dir: Path | None = None,
        memory_bound: int = MEMORY_BOUND,
        database_file: Path | None = None,
    ) -> None:
        """``apply``: one store call; the other arguments are :class:`memory.writer.Writer`'s
        (without a thread, each write runs in :meth:`submit`)."""
        super().__init__(
            lambda writes: [apply(write) for write in writes],
            CODEC,
            spool_path,
            quarantine_path,
            report,
            on_done,
            name="storage writer",
            threaded=threaded,
            queue_size=queue_size,
            spool_dir=spool_dir,
            memory_bound=memory_bound,
            database_file=database_file,
        )
