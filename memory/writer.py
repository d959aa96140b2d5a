"""The background writer: database writes off the caller's thread, in order, never lost silently.

One mechanism for every owner of writes: the profile store (:mod:`dms.storage`) and the
agenda's deliveries and misses (:mod:`agenda.service`). What differs is a parameter: how
a batch of entries is applied (``apply``), spooled and named (:class:`Codec`), how a
failure is classified (``passing``: :func:`passes`), where a result goes (``on_done``)
and the name in reports. :meth:`Writer.submit` never waits on the database. An entry is:

- applied: its result goes to ``on_done`` and to its :class:`Waiter`;
- kept, while the database is away (a lock, a lost connection, a full disk, its SQLite
  file deleted or replaced): it and every entry behind it go to the
  :class:`memory.backlog.Backlog` (a fsync'd spool file, a spare folder, memory as the
  last resort), replayed in order, with backoff, until the database is back; one line
  reports the outage. A full queue overflows into the backlog too. A spool left by a
  crash or a clean exit is replayed at the next start;
- refused for good: it goes to the :class:`memory.spool.Quarantine` file with a report,
  and the entries behind it go on. A batch refused as a whole is applied again one
  entry at a time, so only the refused entry is set aside.

With ``journal=True`` every entry is in the backlog before :meth:`Writer.submit` returns
(write-ahead): it survives a kill -9 (the agenda's deliveries).

The writer thread never dies of a failure: what it did not expect is reported, the
entries go back to the head of the backlog and are retried with backoff. While entries
wait, :attr:`Writer.health` says ``degraded``. :meth:`Writer.close` does not need the
thread: what still waits goes to whichever spool can be written, or one line names how
many entries could not be kept.

Without a thread (``threaded=False``) nothing runs behind the caller's back, so a seeded
run is deterministic: with ``inline=True`` each entry is applied in :meth:`Writer.submit`
and the backlog retried from :meth:`Writer.poll` every :data:`RETRY_EVERY_S` of the
caller's time (the simulator's profile store); otherwise the owner applies what waits
with :meth:`Writer.flush` when it decides to (the agenda).
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from datetime import datetime
from itertools import islice
from pathlib import Path
from typing import Any, Generic, Literal, TypeVar

from sqlalchemy.exc import IntegrityError, SQLAlchemyError
from sqlalchemy.orm.exc import StaleDataError

from memory.backlog import MEMORY_BOUND, Backlog
from memory.errors import ProfileError, StoreUnavailable, one_line
from memory.failures import classify
from memory.spool import Quarantine
from memory.watch import FileWatch

log = logging.getLogger(__name__)

T = TypeVar("T")

QUEUE_SIZE = 1000
"""Entries waiting in memory for the writer thread; beyond it they go to the spool."""
RETRY_EVERY_S = 5.0
"""Between replays of the spool without a writer thread (the simulator's virtual time)."""
BACKOFF_S = (0.25, 8.0)
"""First and longest wait between replays of the spool by the writer thread (doubling)."""
REPLAY_BATCH = 200
"""Spooled entries replayed between two ``done`` marks (one fsync each)."""
CLOSE_TIMEOUT_S = 1.5
"""How long :meth:`Writer.close` waits for the writer to finish its queue."""


def passes(error: BaseException) -> bool:
    """Whether a write that failed with ``error`` may succeed later (keep it and retry)
    rather than be refused for good: :class:`memory.errors.StoreUnavailable`, or a
    database error :func:`memory.failures.classify` calls passing. A bug does not pass."""
    if isinstance(error, ProfileError):
        return isinstance(error, StoreUnavailable)
    if isinstance(error, StaleDataError):
        return True  # another writer changed the row: the write runs again on the new one
    if isinstance(error, IntegrityError):
        return False
    if isinstance(error, SQLAlchemyError):
        return isinstance(classify(error), StoreUnavailable)
    return False


@dataclass(frozen=True, slots=True)
class Codec(Generic[T]):
    """How an entry is spooled, read back and named in reports."""

    to_json: Callable[[T], dict[str, Any]]
    from_json: Callable[[dict[str, Any]], T]
    readable: Callable[[dict[str, Any]], bool]
    """Whether a spooled entry read back can be decoded (the others are set aside)."""
    label: Callable[[T], str]
    """The entry in a report line: a store method, an agenda record."""


@dataclass(frozen=True, slots=True)
class WriterHealth:
    """How the writes are doing, for ``dms/state`` and the operator."""

    status: Literal["ok", "degraded"]
    """``degraded``: writes wait for the database (an outage, a deleted file, a full disk)."""
    pending: int
    """Entries not yet in the database: queued, in flight or waiting in the backlog."""
    reason: str | None = None
    """Why the entries wait (the last failure), when they do."""
    lost: int = 0
    """Entries dropped at the memory bound in this run (no spool could be written)."""


class Waiter:
    """The result of one entry for a caller that may wait for it a little (a profile load)."""

    def __init__(self) -> None:
        self._event = threading.Event()
        self.result: Any = None

    def set(self, result: Any) -> None:
        self.result = result
        self._event.set()

    def wait(self, timeout: float) -> bool:
        return self._event.wait(timeout)


Item = tuple[T, Waiter | None]


class Writer(Generic[T]):
    """Applies entries in order off the caller's thread; spools or quarantines the failed ones."""

    def __init__(
        self,
        apply: Callable[[list[T]], Sequence[Any]],
        codec: Codec[T],
        spool_path: Path | None,
        quarantine_path: Path | None,
        report: Callable[[str, str], None],
        on_done: Callable[[T, Any], None] = lambda entry, result: None,
        *,
        name: str = "writer",
        report_key: str = "memory",
        threaded: bool = True,
        inline: bool = True,
        journal: bool = False,
        batch: int = 1,
        passing: Callable[[BaseException], bool] = passes,
        queue_size: int = QUEUE_SIZE,
        spool_dir: Path | None = None,
        memory_bound: int = MEMORY_BOUND,
        database_file: Path | None = None,
    ) -> None:
        """``apply``: write at most ``batch`` entries, all or none; one result each.
        ``spool_path``: the spool beside the database (None: memory only); ``spool_dir``:
        a spare folder on another filesystem; ``memory_bound``: entries kept in memory
        when no spool can be written; ``quarantine_path``: None keeps refused entries in
        the log only. ``name``: the writer in reports, sent under ``report_key``.
        ``database_file``: the SQLite file to watch (:class:`memory.watch.FileWatch`)."""
        self._apply = apply
        self._codec = codec
        self._report = report
        self._on_done = on_done
        self.name = name
        self._key = report_key
        self._queue_size = queue_size
        self.threaded = threaded
        self._inline = inline and not threaded
        self._journal = journal
        self._batch = max(1, batch)
        self._passing = passing
        self._lock = threading.Lock()
        self._cond = threading.Condition(self._lock)
        self._applying = threading.Lock()  # the thread and flush() take entries in order
        self._queue: deque[Item[T]] = deque()
        self._inflight: list[Item[T]] = []
        self._closing = False
        self._closed = False
        self._now_s = 0.0  # the caller's time without a thread (poll)
        self._retry_at = 0.0
        self._backoff = BACKOFF_S[0]
        self._outage: str | None = None
        """The failure the backlog waits out (its first line), while entries wait."""
        self._faults = 0
        """Unexpected failures of the writer's own work in the current run of them."""
        self._watch = None if database_file is None else FileWatch(database_file)
        self.spool = Backlog(spool_path, spool_dir, memory_bound, codec.readable, self._now)
        self.quarantine = None if quarantine_path is None else Quarantine(quarantine_path)
        self.binds: dict[str, int] = dict(self.spool.binds)
        """Client-side keys (a session's) and the database ids they got."""
        self.replayed = 0
        """Spooled entries applied by this process."""
        self._held = [
            f"{count} unreadable line(s) of the spool {place} were skipped and "
            + (f"kept in {kept}" if kept else "logged (no .bad file could be written)")
            for place, count, kept in self.spool.damaged
        ] + self.spool.news()
        """Lines found while opening, reported at the first :meth:`poll` (the daemon's
        bus opens after the writer)."""
        self._thread: threading.Thread | None = None
        if threaded:
            self._thread = threading.Thread(
                target=self._run, name=f"dms-{name.replace(' ', '-')}", daemon=True
            )

    def start(self) -> None:
        """Start the writer thread (and so the replay of a spool left by an earlier run)."""
        if self._thread is not None and not self._thread.is_alive():
            self._thread.start()

    # ------------------------------------------------------------------ the caller's side

    def submit(self, entry: T, waiter: Waiter | None = None) -> None:
        """Queue ``entry`` (never waits on the database); its result goes to ``waiter``."""
        self._submit([(entry, waiter)])

    def submit_all(self, entries: Sequence[T]) -> None:
        """Queue ``entries`` in order (with ``journal``: one fsync for them all)."""
        if entries:
            self._submit([(entry, None) for entry in entries])

    def _submit(self, items: list[Item[T]]) -> None:
        with self._cond:
            if self._closed:
                raise RuntimeError(f"the {self.name} is closed")
            spool = self._journal or bool(self.spool.pending)
            if not spool and (not self.threaded or len(self._queue) < self._queue_size):
                self._queue.extend(items)
                self._cond.notify_all()
                news: list[str] = []
            else:
                if not self.spool.pending and not self._journal:
                    self._report(
                        self._key,
                        f"write queue full ({self._queue_size}): writes go to the spool "
                        f"{self.spool.where} until the database catches up",
                    )
                self.spool.append([self._codec.to_json(e) for e, _ in items], self.binds)
                for _, waiter in items:
                    if waiter is not None:
                        waiter.set(None)
                news = self.spool.news()
                self._cond.notify_all()
        self._tell(news)
        if self._inline and not spool:
            self.flush()

    def flush(self) -> BaseException | None:
        """Apply what waits now, in the caller's thread, in order (behind what the thread
        is applying). Returns the failure that stopped it while the database is away
        (what is left waits in the backlog), or None when everything is written."""
        while True:
            try:
                with self._applying:
                    progress, failure = self._step(force=True)
            except Exception as error:  # a bug: the entries go back to the backlog
                self._contain(error)
                return error
            if failure is not None or not progress:
                return failure

    def poll(self, now_s: float) -> None:
        """Called every tick: report what was found while opening; an inline writer
        replays the spool when a retry is due at ``now_s``."""
        if self._held:
            held, self._held = self._held, []
            self._tell(held)
        if not self._inline:
            return
        self._now_s = now_s
        if self.spool.pending and now_s >= self._retry_at:
            self.flush()

    def bind(self, key: str, value: int) -> None:
        """``key`` (a session made off the tick) is ``value`` in the database."""
        with self._lock:
            self.binds[key] = value
            if self.spool.pending and not self._closed:
                self.spool.bind(key, value)

    def waiting(self) -> list[T]:
        """The entries not yet in the database, oldest first."""
        with self._lock:
            items = [entry for entry, _ in (*self._inflight, *self._queue)]
            spooled = list(self.spool.pending)
        return [self._codec.from_json(entry) for entry in spooled] + items

    @property
    def pending(self) -> int:
        """Entries not yet in the database: queued, in flight or spooled."""
        with self._lock:
            return self._count()

    def _count(self) -> int:  # lock held
        return len(self._queue) + len(self._inflight) + len(self.spool.pending)

    @property
    def health(self) -> WriterHealth:
        """``ok``, or ``degraded`` while entries wait for the database, with why."""
        with self._lock:
            pending = self._count()
            if not self.spool.pending:
                return WriterHealth("ok", pending, lost=self.spool.lost)
            reason = self._outage or "writes wait for the database"
            if not self.spool.on_disk:
                reason += "; no spool can be written, the writes wait in memory"
            return WriterHealth("degraded", pending, reason, self.spool.lost)

    def wait_idle(self, timeout: float) -> bool:
        """Wait until nothing is queued, in flight or spooled (tests, benchmarks)."""
        with self._cond:
            return self._cond.wait_for(lambda: not self._count(), timeout)

    def close(self, timeout: float = CLOSE_TIMEOUT_S) -> int:
        """Finish the queue, try the spool once, keep what is still waiting in whichever
        spool can be written, and report in one line what is still spooled, or how many
        entries could not be kept. Returns how many entries are not in the database.

        Whether the writer thread finished, is stuck in a database call or died, the
        queue is taken here: nothing depends on the thread.
        """
        with self._cond:
            if self._closed:
                return len(self.spool.pending)
            self._closing = True
            self._cond.notify_all()
        if self._thread is not None:
            if self._thread.is_alive():
                self._thread.join(timeout)
        elif self._inline:
            self.flush()
        with self._cond:
            # What a stuck thread has in flight may land too: a write with a write_id
            # (the profile service's) or an agenda record is then skipped when replayed.
            left = [*self._inflight, *self._queue]
            self._queue.clear()
            self.spool.prepend([self._codec.to_json(e) for e, _ in left], self.binds)
            if left and self._thread is not None:
                log.warning("the %s did not finish; %d write(s) spooled", self.name, len(left))
            self._closed = True
            self.spool.close()
            remaining, kept, lost = len(self.spool.pending), self.spool.on_disk, self.spool.lost
            news = self.spool.news()
            self._cond.notify_all()
        self._tell(news)
        dropped = f"; {lost} more were dropped at the memory bound" if lost else ""
        if remaining and kept:
            self._report(
                self._key,
                f"{remaining} write(s) still spooled in {self.spool.where}; "
                f"they are replayed at the next start{dropped}",
            )
        elif remaining:
            self._report(
                self._key,
                f"{remaining} write(s) could not be kept: no spool can be written "
                f"and the database is away; they are lost at this exit{dropped}",
            )
        elif lost:
            self._report(self._key, f"{lost} write(s) were dropped at the memory bound")
        return remaining

    # ------------------------------------------------------------------ the writer's side

    def _run(self) -> None:
        """The writer thread: never ends before :meth:`close`, whatever fails."""
        tried_at_close = False
        while True:
            try:
                with self._cond:
                    while True:
                        if self._closed:
                            return
                        if self._queue:
                            break
                        if self.spool.pending and (
                            (self._closing and not tried_at_close)
                            or (not self._closing and time.monotonic() >= self._retry_at)
                        ):
                            tried_at_close = self._closing
                            break
                        if self._closing:
                            return
                        wait = None
                        if self.spool.pending:
                            wait = max(0.0, self._retry_at - time.monotonic())
                        if self._watch is not None:
                            self._watch.look_next()
                        self._cond.wait(wait)
                with self._applying:
                    self._step(force=self._closing)
            except Exception as error:  # a bug, or a failure nobody foresaw: never die of it
                self._contain(error)

    def _step(self, force: bool) -> tuple[bool, BaseException | None]:
        """``_applying`` held: apply a batch of the queue, else of the spool (when a retry
        is due, or ``force``). Whether there was anything, and the passing failure."""
        with self._lock:
            if self._closed:
                return False, None
            if self._queue:
                count = min(self._batch, len(self._queue))
                self._inflight = [self._queue.popleft() for _ in range(count)]
                taken = self._inflight
            elif self.spool.pending and (force or self._now() >= self._retry_at):
                taken = []
            else:
                return False, None
        if taken:
            return True, self._execute(taken)
        return True, self._replay()

    def _contain(self, error: Exception) -> None:
        """Put the entries in flight and the queue behind them back at the head of the
        backlog (their order kept), report the first such failure, back off."""
        log.error("the %s failed; it goes on", self.name, exc_info=error)
        with self._cond:
            self._faults += 1
            first = self._faults == 1
            if not self._closed:
                left = [*self._inflight, *self._queue]
                self._queue.clear()
                self.spool.prepend([self._codec.to_json(e) for e, _ in left], self.binds)
                for _, waiter in left:
                    if waiter is not None:
                        waiter.set(None)
            self._inflight = []
            self._outage = self._outage or f"{type(error).__name__}: {error}"
            self._schedule_retry(failed=True)
            news = self.spool.news()
            self._cond.notify_all()
        if first:
            news.insert(
                0,
                f"the {self.name} failed ({type(error).__name__}: {error}); it goes on, "
                "and retries the waiting writes with backoff",
            )
        self._tell(news)

    def _now(self) -> float:
        return time.monotonic() if self.threaded else self._now_s

    def _tell(self, lines: list[str]) -> None:
        """Report lines (the backlog's news); never under the lock."""
        for line in lines:
            self._report(self._key, line)

    def _apply_all(self, entries: list[T], size: int) -> tuple[list[Any], BaseException | None]:
        """Apply ``entries`` in order, ``size`` at a time: the results of those done (None
        for one set aside, refused for good) and the passing failure that stopped the rest."""
        results: list[Any] = []
        while len(results) < len(entries):
            chunk = entries[len(results) : len(results) + size]
            try:
                if self._watch is not None:
                    self._watch.check(self._now())
                got = list(self._apply(chunk))
            except Exception as error:
                if self._passing(error):
                    return results, error
                if len(chunk) > 1:  # one at a time: only the refused entry is set aside
                    more, failure = self._apply_all(chunk, 1)
                    results += more
                    if failure is not None:
                        return results, failure
                    continue
                entry = chunk[0]
                self._quarantine(self._codec.label(entry), self._codec.to_json(entry), error)
                results.append(None)
                continue
            for entry, result in zip(chunk, got, strict=True):
                try:
                    self._on_done(entry, result)
                except Exception:
                    log.exception("after %s", self._codec.label(entry))
            results += got
        return results, None

    def _execute(self, items: list[Item[T]]) -> BaseException | None:
        """Apply entries taken from the queue; on a passing failure, the rest and the
        queue behind go to the head of the backlog, and the first of an outage is reported."""
        results, failure = self._apply_all([entry for entry, _ in items], self._batch)
        done = len(results)
        for (_, waiter), result in zip(items, results, strict=False):
            if waiter is not None:
                waiter.set(result)
        if failure is None:
            with self._cond:
                self._inflight = []
                self._faults = 0
                self._cond.notify_all()
            return None
        first, count, news = False, 0, []
        with self._cond:
            if not self._closed:  # the entries stay in flight until they are in the backlog
                left = [*items[done:], *self._queue]
                self._queue.clear()
                self.spool.prepend([self._codec.to_json(e) for e, _ in left], self.binds)
                for _, waiter in left:
                    if waiter is not None:
                        waiter.set(None)
                first = self._outage is None
                self._outage = self._outage or one_line(failure)
                self._schedule_retry(failed=True)
                news = self.spool.news()
                count = len(self.spool.pending)
            self._inflight = []
            self._cond.notify_all()
        if first:
            self._tell_outage(items[done][0], failure, count)
        self._tell(news)
        return failure

    def _replay(self) -> BaseException | None:
        """Apply a batch from the head of the spool; the failure when the database is
        still away."""
        with self._lock:
            self.spool.retry()  # a backlog kept in memory: back on disk when it can be
            batch = list(islice(self.spool.pending, REPLAY_BATCH))
            news = self.spool.news()
        self._tell(news)
        entries: list[T] = []
        unreadable: tuple[dict[str, Any], Exception] | None = None
        for raw in batch:
            try:
                entries.append(self._codec.from_json(raw))
            except (KeyError, TypeError, ValueError) as error:
                unreadable = raw, error  # set aside once everything before it is done
                break
        results, failure = self._apply_all(entries, self._batch)
        done = len(results)
        self.replayed += done
        if failure is None and unreadable is not None:
            self._quarantine("an unreadable spooled entry", *unreadable)
            done += 1
        first, count = False, 0
        with self._cond:
            if self._closed:
                return failure
            self.spool.done(done)
            self._schedule_retry(failed=failure is not None)
            if failure is not None:
                first = self._outage is None
                self._outage = one_line(failure)
                count = len(self.spool.pending)
            elif not self.spool.pending:
                if self._outage is not None:
                    log.warning("the database is back: the %s replayed its spool", self.name)
                self._outage = None
                self._faults = 0
            news = self.spool.news()
            self._cond.notify_all()
        if first and failure is not None:
            self._tell_outage(entries[done], failure, count)
        self._tell(news)
        return failure

    def _tell_outage(self, entry: T, failure: BaseException, count: int) -> None:
        """The one line of an outage; the entries behind it are spooled silently."""
        self._report(
            self._key,
            f"{self._codec.label(entry)} failed, will retry: {one_line(failure)}; {count} write(s) "
            f"are spooled to {self.spool.where} and replayed in order when the "
            "database is back",
        )

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

    def _quarantine(self, label: str, entry: dict[str, Any], error: BaseException) -> None:
        """Keep an entry the database refused for good, and report it in one line."""
        reason = one_line(error)
        if not isinstance(error, ProfileError):
            log.error("%s failed unexpectedly", label, exc_info=error)
            reason = f"{type(error).__name__}: {reason}"
        record = {"time": datetime.now().astimezone().isoformat(), "error": reason, **entry}
        if self.quarantine is None:
            log.error("%s refused: %s", label, record)
            where = "it is in the log"
        else:
            try:
                self.quarantine.add(record)
                where = f"quarantined in {self.quarantine.path}"
            except OSError as disk:
                log.error("cannot quarantine %s: %s: %s", label, disk, record)
                where = f"cannot quarantine it ({disk}); it is in the log"
        self._report(self._key, f"{label} refused: {reason}; {where}")
