"""The storage writer: the daemon's database writes, off the tick thread, never lost silently.

The controller hands every store write to :meth:`StorageWriter.submit`, which never
waits on the database. A writer thread applies the writes in order from a bounded
queue. What happens to a write:

- applied: its result goes to ``on_done`` (the profile cache);
- the database is unavailable for a while (:class:`memory.StoreUnavailable`: a lock,
  a lost connection, a timeout): the write and every write behind it go to the
  :class:`memory.spool.Spool` (fsync'd), which is replayed in order, with backoff, until
  the database is back; one line reports the outage. A full queue overflows into the
  spool too. A spool left by a crash or a clean exit is replayed at the next start;
- refused for good (:class:`memory.errors.StoreRefused`, or any other error: a
  constraint, a value the database cannot hold, a missing table): the write goes to the
  :class:`memory.spool.Quarantine` file with a report, and the writes behind it go on.

With ``threaded=False`` (the simulator, on a virtual clock) writes run inline in
:meth:`submit` and the spool is retried from :meth:`poll`, every :data:`RETRY_EVERY_S`
of the caller's time, so that a seeded run is deterministic.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import datetime
from itertools import islice
from pathlib import Path
from typing import Any

from memory.errors import ProfileError, StoreUnavailable
from memory.spool import Quarantine, Spool

log = logging.getLogger(__name__)

QUEUE_SIZE = 1000
"""Writes waiting in memory for the writer thread; beyond it they go to the spool."""
RETRY_EVERY_S = 5.0
"""Between replays of the spool without a writer thread (the simulator's virtual time)."""
BACKOFF_S = (0.25, 8.0)
"""First and longest wait between replays of the spool by the writer thread (doubling)."""
REPLAY_BATCH = 200
"""Spooled writes replayed between two ``done`` marks (one fsync each)."""
CLOSE_TIMEOUT_S = 1.5
"""How long :meth:`StorageWriter.close` waits for the writer to finish its queue."""


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


@dataclass(frozen=True, slots=True)
class Write:
    """One store call, ``method(*args, **kwargs)``, as it is queued, spooled and replayed."""

    method: str
    args: tuple[Any, ...] = ()
    kwargs: dict[str, Any] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        return {"op": self.method, "args": encode(self.args), "kwargs": encode(self.kwargs)}

    @classmethod
    def from_json(cls, entry: dict[str, Any]) -> Write:
        return cls(str(entry["op"]), tuple(decode(entry["args"])), dict(decode(entry["kwargs"])))


class Waiter:
    """The result of one write for a caller that may wait for it a little (a profile load)."""

    def __init__(self) -> None:
        self._event = threading.Event()
        self.result: Any = None

    def set(self, result: Any) -> None:
        self.result = result
        self._event.set()

    def wait(self, timeout: float) -> bool:
        return self._event.wait(timeout)

    @property
    def done(self) -> bool:
        return self._event.is_set()


class StorageWriter:
    """Applies writes in order off the caller's thread; spools or quarantines the failed ones."""

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
    ) -> None:
        self._apply = apply
        self._report = report
        self._on_done = on_done
        self._queue_size = queue_size
        self._lock = threading.Lock()
        self._cond = threading.Condition(self._lock)
        self._queue: deque[tuple[Write, Waiter | None]] = deque()
        self._inflight: tuple[Write, Waiter | None] | None = None
        self._closing = False
        self._closed = False
        self._now_s = 0.0  # the caller's time without a thread (poll)
        self._retry_at = 0.0
        self._backoff = BACKOFF_S[0]
        self.spool = Spool(spool_path)
        self.quarantine = Quarantine(quarantine_path)
        self.binds: dict[str, int] = dict(self.spool.binds)
        """Client-side keys (a session's) and the database ids they got."""
        self.replayed = 0
        """Spooled writes applied by this process."""
        if self.spool.pending:
            log.warning(
                "replaying %d spooled write(s) from %s", len(self.spool.pending), spool_path
            )
        self._thread: threading.Thread | None = None
        if threaded:
            self._thread = threading.Thread(target=self._run, name="dms-storage", daemon=True)

    def start(self) -> None:
        """Start the writer thread (and so the replay of a spool left by an earlier run)."""
        if self._thread is not None and not self._thread.is_alive():
            self._thread.start()

    # ------------------------------------------------------------------ the caller's side

    def submit(self, write: Write, waiter: Waiter | None = None) -> None:
        """Queue ``write`` (never waits on the database); its result goes to ``waiter``."""
        with self._cond:
            if self._closed:
                raise RuntimeError("the storage writer is closed")
            if self.spool.pending:
                self._spool_late([write], waiter)
                return
            if self._thread is not None:
                if len(self._queue) >= self._queue_size:
                    self._report(
                        "memory",
                        f"write queue full ({self._queue_size}): writes go to the spool "
                        f"{self.spool.path} until the database catches up",
                    )
                    self._spool_late([write], waiter)
                    return
                self._queue.append((write, waiter))
                self._cond.notify_all()
                return
        self._execute(write, waiter)

    def _spool_late(self, writes: list[Write], waiter: Waiter | None) -> None:
        """Append behind the spooled writes (lock held): order is kept."""
        entries = [w.to_json() for w in writes]
        self.spool.append(entries, self.binds)
        if waiter is not None:
            waiter.set(None)

    def poll(self, now_s: float) -> None:
        """Without a writer thread: replay the spool when a retry is due at ``now_s``."""
        if self._thread is not None:
            return
        self._now_s = now_s
        if self.spool.pending and now_s >= self._retry_at:
            while self.spool.pending and self._replay():
                pass

    def bind(self, key: str, value: int) -> None:
        """``key`` (a session made off the tick) is ``value`` in the database."""
        with self._lock:
            self.binds[key] = value
            if self.spool.pending and not self._closed:
                self.spool.bind(key, value)

    @property
    def pending(self) -> int:
        """Writes not yet in the database: queued, in flight or spooled."""
        with self._lock:
            return len(self._queue) + (self._inflight is not None) + len(self.spool.pending)

    def wait_idle(self, timeout: float) -> bool:
        """Wait until nothing is queued, in flight or spooled (tests, benchmarks)."""
        with self._cond:
            return self._cond.wait_for(
                lambda: not self._queue and self._inflight is None and not self.spool.pending,
                timeout,
            )

    def close(self, timeout: float = CLOSE_TIMEOUT_S) -> int:
        """Finish the queue (what cannot be written goes to the spool), try the spool once,
        and report in one line what is still spooled. Returns that number."""
        with self._cond:
            if self._closed:
                return len(self.spool.pending)
            self._closing = True
            self._cond.notify_all()
        if self._thread is not None:
            self._thread.join(timeout)
        else:
            self._retry_at = 0.0
            self.poll(self._now_s)
        with self._cond:
            if self._thread is not None and self._thread.is_alive():
                # Stuck in a database call: keep the write in flight and the queue. The
                # one in flight may also land: a write with a write_id (the profile
                # service's) is then skipped by the store when it is replayed.
                left = ([self._inflight] if self._inflight else []) + list(self._queue)
                self._queue.clear()
                self.spool.prepend([w.to_json() for w, _ in left], self.binds)
                log.warning("the storage writer did not finish; %d write(s) spooled", len(left))
            self._closed = True
            remaining = len(self.spool.pending)
            self.spool.close()
            self._cond.notify_all()
        if remaining:
            self._report(
                "memory",
                f"{remaining} write(s) still spooled in {self.spool.path}; "
                "they are replayed at the next start",
            )
        return remaining

    # ------------------------------------------------------------------ the writer's side

    def _run(self) -> None:
        tried_at_close = False
        while True:
            with self._cond:
                while True:
                    if self._closed:
                        return
                    if self._queue:
                        item: tuple[Write, Waiter | None] | None = self._queue.popleft()
                        self._inflight = item
                        break
                    if self.spool.pending and (
                        (self._closing and not tried_at_close)
                        or (not self._closing and time.monotonic() >= self._retry_at)
                    ):
                        tried_at_close = self._closing
                        item = None
                        break
                    if self._closing:
                        return
                    wait = None
                    if self.spool.pending:
                        wait = max(0.0, self._retry_at - time.monotonic())
                    self._cond.wait(wait)
            if item is not None:
                self._execute(*item)
            else:
                self._replay()

    def _now(self) -> float:
        return time.monotonic() if self._thread is not None else self._now_s

    def _execute(self, write: Write, waiter: Waiter | None) -> None:
        result: Any = None
        try:
            result = self._apply(write)
        except StoreUnavailable as error:
            first = False
            with self._cond:
                self._inflight = None
                if not self._closed:
                    first = not self.spool.pending
                    behind = list(self._queue)
                    self._queue.clear()
                    entries = [w.to_json() for w in (write, *(w for w, _ in behind))]
                    self.spool.prepend(entries, self.binds)
                    for _, other in behind:
                        if other is not None:
                            other.set(None)
                    self._schedule_retry(failed=True)
                self._cond.notify_all()
            if first:  # one line per outage; the writes behind it are spooled silently
                self._report(
                    "memory",
                    f"{write.method} failed, will retry: {error}; writes are spooled to "
                    f"{self.spool.path} and replayed in order when the database is back",
                )
            result = None
        except Exception as error:  # refused for good, or a bug: set aside, the rest goes on
            self._set_aside(write, error)
            with self._cond:
                self._inflight = None
                self._cond.notify_all()
        else:
            self._on_done(write, result)
            with self._cond:
                self._inflight = None
                self._cond.notify_all()
        if waiter is not None:
            waiter.set(result)

    def _replay(self) -> bool:
        """Apply a batch from the head of the spool; False when the database is still away."""
        with self._lock:
            batch = list(islice(self.spool.pending, REPLAY_BATCH))
        done = 0
        failure: StoreUnavailable | None = None
        for entry in batch:
            try:
                write = Write.from_json(entry)
            except (KeyError, TypeError, ValueError) as error:
                self._set_aside(Write(str(entry.get("op", "?"))), error, entry)
                done += 1
                continue
            try:
                result = self._apply(write)
            except StoreUnavailable as error:
                failure = error
                break
            except Exception as error:
                self._set_aside(write, error)
            else:
                self._on_done(write, result)
                self.replayed += 1
            done += 1
        with self._cond:
            if self._closed:
                return False
            self.spool.done(done)
            self._schedule_retry(failed=failure is not None)
            if not self.spool.pending:
                log.warning("the database is back: spooled writes replayed")
            self._cond.notify_all()
        return failure is None

    def _schedule_retry(self, failed: bool) -> None:
        """Lock held: when to try the spool next."""
        if not failed:
            self._backoff = BACKOFF_S[0]
            self._retry_at = 0.0
            return
        if self._thread is None:
            self._retry_at = self._now_s + RETRY_EVERY_S
            return
        self._retry_at = time.monotonic() + self._backoff
        self._backoff = min(self._backoff * 2, BACKOFF_S[1])

    def _set_aside(
        self, write: Write, error: BaseException, entry: dict[str, Any] | None = None
    ) -> None:
        """Quarantine a write the database refused for good, and report it in one line."""
        reason = str(error).strip().splitlines()[0] if str(error).strip() else type(error).__name__
        if not isinstance(error, ProfileError):
            log.error("%s failed unexpectedly", write.method, exc_info=error)
            reason = f"{type(error).__name__}: {reason}"
        record = {
            "time": datetime.now().astimezone().isoformat(),
            "error": reason,
            **(entry if entry is not None else write.to_json()),
        }
        try:
            self.quarantine.add(record)
            where = f"quarantined in {self.quarantine.path}"
        except OSError as disk:
            log.error("cannot quarantine %s: %s: %s", write.method, disk, record)
            where = f"cannot quarantine it ({disk}); it is in the log"
        self._report("memory", f"{write.method} refused: {reason}; {where}")
