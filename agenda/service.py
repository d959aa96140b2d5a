"""The agenda: events and reminders per user, stored in the daemon's database.

The controller calls :meth:`Agenda.due` on every tick; it answers from the
in-memory :class:`agenda.index.AgendaIndex`, without SQL. Deliveries are written at
once (:meth:`Agenda.delivered`); misses are queued and written within
:data:`FLUSH_AFTER_S` (and before any read of the log), which keeps the tick cheap.
A miss that is lost in a crash is found again on restart, because the item's cursor
in the database moves only when its occurrence is logged.

Every delivery and miss is also appended to a journal (the daemon's, on by default
with ``background=True``: :func:`memory.db.side_file` ``(url, "agenda-spool")``, a
:class:`memory.spool.Spool`) and ``fsync``'d before the call that records it returns; the
background thread writes it to the database and marks it done. A kill -9 while the write
waits (another process holds SQLite's lock, PostgreSQL is away) loses nothing: the next
start replays the journal into the database before it computes what is due, so an
occurrence delivered before the crash is never delivered again.

With ``background=True`` (the daemon) the calls from the tick (:meth:`Agenda.due`,
:meth:`Agenda.delivered`, :meth:`Agenda.user_perceived`) never touch the database: their
writes and reads run on one background thread, in order. Database I/O never holds the
index's lock (``_lock``), only ``_io_lock``, which serializes it; so a locked or absent
database never stalls the tick. Lock order: ``_io_lock`` before ``_lock``, never the
other way; ``_journal_lock`` comes after both.

Several robots share one agenda (docs/fleet.md). An occurrence is *claimed* before
:meth:`Agenda.due` returns it: a row in ``agenda_claims`` keyed by (item, fire time),
inserted with ``ON CONFLICT DO NOTHING``, so of two robots that see the user in the same
second one gets it and the other never returns it (it records it missed at the end of
the grace time if nobody delivered it; a delivery wins over such a miss in the log).
Without the database no claim can be made: on a server database the occurrence waits
(it is claimed when the database is back, or missed), on a SQLite file, which only robots
on one machine share, it is delivered anyway (``offline_delivery``). Items added
elsewhere (another robot, the command line) are polled for every :data:`POLL_S` of the
caller's clock, and the whole agenda is reloaded every :data:`RELOAD_S`.
"""

from __future__ import annotations

import logging
import os
import socket
import threading
import uuid
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from concurrent.futures import wait as wait_for
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

from sqlalchemy import (
    Connection,
    Engine,
    bindparam,
    delete,
    insert,
    inspect,
    make_url,
    select,
    update,
)
from sqlalchemy.dialects import postgresql, sqlite
from sqlalchemy.exc import IntegrityError, SQLAlchemyError
from sqlalchemy.orm import Session, sessionmaker

from agenda import migrations
from agenda.errors import AgendaError, AgendaNotFound
from agenda.index import US_PER_S, AgendaIndex, Entry, MissedRun
from agenda.items import (
    AgendaItem,
    DueItem,
    ItemKind,
    ItemSpec,
    Occurrence,
    Outcome,
    Priority,
    UpcomingItem,
)
from agenda.models import ClaimRow, ItemRow, OccurrenceRow, UtcDateTime
from agenda.schedule import (
    MAX_EVERY_S,
    Schedule,
    ScheduleKind,
    build,
    from_us,
    localize,
    to_us,
    zone,
)
from dms.kernel.activity_names import ACTIVITIES
from dms.kernel.ids import InvalidIdentifier, check_identifier
from memory.db import as_url, make_engine, side_file
from memory.spool import Spool
from memory.store import register_user_data

log = logging.getLogger(__name__)

FLUSH_AFTER_S = 300
"""Longest time a recorded miss waits in memory before it is written."""
RETRY_AFTER_S = 5
BACKGROUND_BUSY_TIMEOUT_S = 1.0
"""SQLite lock wait of the background thread: it retries later rather than wait long."""
MAX_LEAD_S = 86400
MAX_GRACE_S = 7 * 86400
MAX_TEXT = 500


CLAIM_WAIT_S = 0.05
"""How long :meth:`Agenda.due` waits for a claim made off the tick (``background``):
enough for a healthy database, so the item comes out in the same tick; else it comes
out of a later one."""
CLAIM_RETRY_S = 2
"""Between claims of one occurrence while the database cannot be reached."""
POLL_S = 10
"""Between reads of items added since the last one (by another robot, the command line)."""
POLL_OVERLAP = 100
"""Ids below the highest seen that a poll reads again (ids committed out of order)."""
RELOAD_S = 300
"""Between reloads of every item (items removed elsewhere, cursors moved elsewhere)."""
CLAIMS_KEEP_S = MAX_GRACE_S + MAX_LEAD_S + 86400
"""How long a claim is kept after its fire time: past it the occurrence is settled."""

_MINE, _THEIRS, _PENDING, _RETRY = "mine", "theirs", "pending", "retry"

JOURNAL_SUFFIX = "agenda-spool"
"""The journal's file: ``<db file>.agenda-spool``, or in the state folder for a server."""


@dataclass(frozen=True, slots=True)
class _Record:
    """One delivery or miss waiting for the database: its log row and the item's new cursor.

    ``entry`` is JSON-able (it is what the journal holds); ``journaled`` says whether it
    is in the journal, so that a flush marks exactly those done.
    """

    item_id: int
    entry: dict[str, Any]
    journaled: bool


def journal_path(url: str, owner: str | None = None) -> Path | None:
    """Where the agenda's journal for ``url`` lives (``owner``'s own: a robot id); None
    for an in-memory database."""
    parsed = make_url(as_url(url))  # a plain file path (``--db dms.db``) too
    if parsed.get_backend_name() == "sqlite" and parsed.database in (None, "", ":memory:"):
        return None
    return side_file(url, JOURNAL_SUFFIX, owner)


def _one_line(error: BaseException) -> str:
    text = str(getattr(error, "orig", None) or error)
    return text.splitlines()[0] if text else type(error).__name__


class Agenda:
    """Every user's events and reminders; the controller's view of what is due."""

    def __init__(
        self,
        url: str,
        user_exists: Callable[[str], bool] | None = None,
        background: bool = False,
        journal: bool | None = None,
        claimer: str | None = None,
        offline_delivery: bool | None = None,
        poll_s: float | None = POLL_S,
        unseen_misses: bool | None = None,
    ) -> None:
        """Open the agenda at ``url``, replay its journal and load every item.

        ``journal``: keep deliveries and misses in the fsync'd journal until the database
        has them (default: with ``background``, i.e. in the daemon). Only one process may
        journal for a database: the command line never does.

        ``claimer``: who claims occurrences, the robot's id (a robot restarted after a
        claim delivers what it claimed); default: one made for this process.
        ``offline_delivery``: deliver an occurrence that cannot be claimed because the
        database is away (default: on a SQLite file only). ``poll_s``: between polls for
        items added elsewhere, of the caller's clock (None: never). ``unseen_misses``:
        record the misses of users this robot has not seen since the occurrence fell due
        (default: on a SQLite file only; in a fleet each robot would write every miss of
        every user again: the robot that next sees the user records them, from the
        cursor in the database).
        """
        self.claimer = claimer or f"{socket.gethostname()}-{os.getpid()}-{uuid.uuid4().hex[:8]}"
        self._claims: dict[tuple[int, int], tuple[str, int]] = {}
        self._seen: dict[str, int] = {}
        """User -> when this robot last saw them (perceived, or present at ``due``)."""
        """(item, fire time) -> (state, retry time): what this robot knows of its claims."""
        self._poll_us = None if poll_s is None else round(poll_s * US_PER_S)
        self._poll_at_us: int | None = None
        self._reload_at_us: int | None = None
        self._high_id = 0
        self.claims_lost = 0
        """Occurrences another robot claimed first."""
        self._user_exists = user_exists
        self._lock = threading.RLock()
        self._io_lock = threading.Lock()
        self._journal_lock = threading.Lock()
        self._journal: Spool | None = None
        self._jobs = (
            ThreadPoolExecutor(max_workers=1, thread_name_prefix="dms-agenda")
            if background
            else None
        )
        self._index = AgendaIndex()
        self._queue: list[_Record] = []
        self._flush_at_us: int | None = None
        self._schedules: dict[tuple[str, str, str, datetime | None], Schedule] = {}
        self.problems: list[str] = []
        """Stored items that could not be loaded (bad spec, unknown zone), one line each."""
        try:
            self._engine: Engine = make_engine(
                url, BACKGROUND_BUSY_TIMEOUT_S if background else None
            )
        except (SQLAlchemyError, OSError) as error:
            raise AgendaError(f"cannot open the agenda at {url}: {_one_line(error)}") from None
        try:
            self._prepare_schema()
            self._sessions = sessionmaker(self._engine, expire_on_commit=False)
            local = self._engine.dialect.name == "sqlite"
            self._offline_delivery = local if offline_delivery is None else offline_delivery
            self._unseen_misses = local if unseen_misses is None else unseen_misses
            path = (
                journal_path(url, claimer) if (background if journal is None else journal) else None
            )
            if path is not None:
                self._journal = Spool(path)
                self._replay_journal()
            self._load(None)
            self._apply_queued()
        except (SQLAlchemyError, OSError) as error:
            self._close_journal()
            self._engine.dispose()
            raise AgendaError(f"cannot open the agenda at {url}: {_one_line(error)}") from None
        except AgendaError:
            self._close_journal()
            self._engine.dispose()
            raise

    def _replay_journal(self) -> None:
        """At start: write what the journal holds (a crash's or an outage's), in order.

        Runs before the items are loaded, so their cursors already count these records.
        If the database will not take them now (another process holds its lock), they
        stay queued and journaled, :meth:`_apply_queued` moves the cursors in memory, and
        the next flush writes them.
        """
        assert self._journal is not None
        entries = list(self._journal.pending)
        if not entries:
            return
        self._queue = [_Record(int(e["item_id"]), e, True) for e in entries]
        try:
            self._flush()
        except AgendaError as error:
            log.warning("%s; %d journaled record(s) kept for later", error, len(entries))
            self._flush_at_us = 0
            return
        log.info("agenda: %d journaled record(s) replayed into the database", len(entries))

    def _apply_queued(self) -> None:
        """Move the loaded items' cursors past the records still queued (journal replay)."""
        with self._lock:
            for record in self._queue:
                if record.item_id in self._index.entries:
                    cursor = record.entry["cursor_us"]
                    self._index.delivered(record.item_id, None if cursor is None else int(cursor))

    def _close_journal(self) -> None:
        with self._journal_lock:
            if self._journal is not None:
                self._journal.close()
                self._journal = None

    def _enqueue(self, entries: list[dict[str, Any]]) -> None:
        """Queue records for the database, journaled first (``_lock`` held: keeps the order).

        A journal that cannot be written (disk full) is reported and the records are kept
        in memory only, as without a journal.
        """
        journaled = False
        with self._journal_lock:
            if self._journal is not None:
                try:
                    self._journal.append(entries)
                    journaled = True
                except OSError as error:
                    log.error(
                        "agenda: cannot write the journal %s (%s); %d record(s) in memory only",
                        self._journal.path,
                        error,
                        len(entries),
                    )
        self._queue.extend(_Record(int(e["item_id"]), e, journaled) for e in entries)

    def _offload(self, job: Callable[[], None]) -> Future[None] | None:
        """Run ``job`` on the background thread, or at once without one (never under _lock).

        Returns the background job's future (None when it ran at once or was refused)."""
        if self._jobs is None:
            job()
            return None
        try:
            return self._jobs.submit(self._guarded, job)
        except RuntimeError:  # shut down: the caller is closing, close() flushes
            log.warning("agenda: closing, %s left to close()", getattr(job, "__name__", job))
            return None

    @staticmethod
    def _guarded(job: Callable[[], None]) -> None:
        try:
            job()
        except Exception:  # a background job must not die silently; the next one retries
            log.exception("agenda: background database work failed")

    # ------------------------------------------------------------------ schema

    def _prepare_schema(self) -> None:
        head = migrations.head()
        with self._engine.connect() as connection:
            revision = migrations.current(connection)
            installed = migrations.installed(connection)
            tables = set(inspect(connection).get_table_names())
        if revision == head:
            missing = [
                name
                for name in (
                    ItemRow.__tablename__,
                    OccurrenceRow.__tablename__,
                    ClaimRow.__tablename__,
                )
            ]
            missing = [name for name in missing if name not in tables]
            if missing:
                raise AgendaError(
                    f"the database is damaged: the agenda's table {', '.join(missing)} is "
                    "missing; restore a backup, or run `dms db upgrade` to recreate it empty"
                )
            return
        if revision is None and not installed:
            try:
                migrations.upgrade_engine(self._engine)
            except SQLAlchemyError:
                # Another process may have created it at the same time.
                with self._engine.connect() as connection:
                    if migrations.current(connection) != head:
                        raise
            return
        raise AgendaError(
            f"the agenda's tables are at revision {revision or 'none'}, this dms needs "
            f"{head}: run `dms db upgrade`"
        )

    @property
    def engine(self) -> Engine:
        """The agenda's database engine (the simulator sets its throw-away file's sync)."""
        return self._engine

    def close(self) -> None:
        """Finish the background work, write what is queued and release the database.

        With a journal, what the database will not take now stays journaled for the next
        start (one log line says how much); without one, AgendaError.
        """
        if self._jobs is not None:
            self._jobs.shutdown(wait=True)
        try:
            self._flush()
        except AgendaError as error:
            with self._journal_lock:
                kept = 0 if self._journal is None else len(self._journal)
            if not kept:
                raise
            log.warning(
                "%s; %d agenda record(s) kept in the journal for the next start", error, kept
            )
        finally:
            self._close_journal()
            self._engine.dispose()

    # ------------------------------------------------------------------ management

    def add(self, spec: ItemSpec, now: datetime) -> AgendaItem:
        """Store a new item; AgendaError (one line, nothing stored) when it is invalid."""
        row, schedule = self._validate(spec, now)
        with self._io_lock:
            try:
                with self._sessions.begin() as session:
                    session.add(row)
                    session.flush()
                    item = _item(row)
            except SQLAlchemyError as error:
                raise AgendaError(f"cannot store the agenda item: {_one_line(error)}") from None
            with self._lock:
                self._index.put(self._entry(item, schedule))
                self._high_id = max(self._high_id, item.item_id)
            return item

    def get(self, item_id: int) -> AgendaItem:
        """The stored item ``item_id``; AgendaNotFound if there is none."""
        with self._sessions() as session:
            row = session.get(ItemRow, item_id)
            if row is None:
                raise AgendaNotFound(f"no agenda item {item_id}")
            return _item(row)

    def remove(self, item_id: int) -> None:
        """Delete item ``item_id`` (its log stays); AgendaNotFound if there is none."""
        self._flush()
        with self._io_lock:
            try:
                with self._sessions.begin() as session:
                    deleted = session.execute(delete(ItemRow).where(ItemRow.id == item_id))
            except SQLAlchemyError as error:
                raise AgendaError(
                    f"cannot remove agenda item {item_id}: {_one_line(error)}"
                ) from None
            with self._lock:
                known = self._index.drop(item_id)
        if not deleted.rowcount and not known:  # type: ignore[attr-defined]
            raise AgendaNotFound(f"no agenda item {item_id}")

    def upcoming(self, user_id: str | None, now: datetime, limit: int = 20) -> list[UpcomingItem]:
        """Each item's next occurrence (or the one waiting now), soonest first.

        Reads the database first, so it shows items added by another process.
        """
        self._flush()
        self._load(user_id)
        with self._lock:
            return self._index.upcoming(user_id, to_us(now), max(0, limit))

    # ------------------------------------------------------------------ the controller

    def user_perceived(self, user_id: str, now: datetime) -> None:
        """The robot sees ``user_id``: load their schedule from the database (paper, step 5).

        In the background with ``background=True``: the index is updated when the read lands.
        """
        with self._lock:
            self._seen[user_id] = max(self._seen.get(user_id, 0), to_us(now))

        def perceive() -> None:
            try:
                self._flush()
            except AgendaError as error:
                log.warning("%s; retrying in %s s", error, RETRY_AFTER_S)
            self._load(user_id)
            with self._lock:
                self._advance(to_us(now), down=False)

        self._offload(perceive)

    def recover(self, now: datetime) -> list[DueItem]:
        """At daemon start: settle what fell due while it was down.

        Occurrences still within their grace time wait for their user (and come out of
        :meth:`due`); older ones are recorded as missed. Returns those that wait. The
        journal was replayed when the agenda was opened, so nothing delivered before a
        crash waits again; with a journal, a database that will not take the misses now
        (locked) gets them later.
        """
        with self._lock:
            self._advance(to_us(now), down=True)
        try:
            self._flush()
        except AgendaError as error:
            if self._journal is None:
                raise
            log.warning("%s; journaled, retrying in %s s", error, RETRY_AFTER_S)
            with self._lock:
                self._flush_at_us = to_us(now) + RETRY_AFTER_S * US_PER_S
        with self._lock:
            return self._index.all_waiting()

    def due(self, now: datetime, present_user: str | None) -> list[DueItem]:
        """What is due now for ``present_user`` and claimed by this robot, highest priority
        first. Called every tick.

        Items of absent users wait up to their grace time and are then recorded as
        missed by this call. An item waiting for the present user is claimed first
        (off the tick with ``background``, waiting at most :data:`CLAIM_WAIT_S`); one
        another robot claimed is never returned.
        """
        now_us = to_us(now)
        flush = poll = False
        with self._lock:
            if self._index.has_work(now_us):
                self._advance(now_us, down=False)
            if self._flush_at_us is not None and now_us >= self._flush_at_us:
                flush = True
                self._flush_at_us = now_us + RETRY_AFTER_S * US_PER_S  # unless it succeeds
            if self._poll_us is not None:
                if self._poll_at_us is None:
                    self._poll_at_us = now_us + self._poll_us
                elif now_us >= self._poll_at_us:
                    poll = True
                    self._poll_at_us = now_us + self._poll_us
            if present_user is not None and now_us >= self._seen.get(present_user, 0):
                self._seen[present_user] = now_us
            waiting = [] if present_user is None else self._index.waiting_for(present_user)
            to_claim = [item for item in waiting if self._needs_claim(item, now_us)]
            for item in to_claim:
                self._claims[_key(item)] = (_PENDING, 0)
        if flush:
            self._offload(self._flush_or_retry(now_us))
        if poll:
            self._offload(self._poll(now_us))
        if to_claim:
            future = self._offload(self._claim_job(to_claim, now_us))
            if future is not None:
                wait_for([future], timeout=CLAIM_WAIT_S)
        if not waiting:
            return []
        assert present_user is not None
        with self._lock:
            return [
                item
                for item in self._index.waiting_for(present_user)
                if self._claims.get(_key(item), ("", 0))[0] == _MINE
            ]

    def wait_idle(self, timeout: float) -> bool:
        """Wait until the background work queued so far is done (tests, benchmarks)."""
        if self._jobs is None:
            return True
        try:
            future = self._jobs.submit(lambda: None)
        except RuntimeError:
            return True
        done, _ = wait_for([future], timeout=timeout)
        return bool(done)

    def claim(self, item: DueItem, now: datetime) -> bool:
        """Claim one occurrence for this robot now, in the database; whether it is ours.

        What :meth:`due` does for each item it returns; True again for an occurrence
        this robot (this ``claimer``) claimed before, False once another robot has it.
        """
        now_us = to_us(now)
        self._claim_job([item], now_us)()
        with self._lock:
            return self._claims.get(_key(item), ("", 0))[0] == _MINE

    def _needs_claim(self, item: DueItem, now_us: int) -> bool:
        """``_lock`` held: whether ``item`` must be claimed (again) now."""
        state, retry_us = self._claims.get(_key(item), ("", 0))
        return state == "" or (state == _RETRY and now_us >= retry_us)

    def _claim_job(self, items: list[DueItem], now_us: int) -> Callable[[], None]:
        """A job that claims ``items`` in one transaction and notes the outcomes."""

        def claim() -> None:
            try:
                with self._io_lock, self._engine.begin() as connection:
                    outcomes = [_claim(connection, item, self.claimer, now_us) for item in items]
            except SQLAlchemyError as error:
                offline = self._offline_delivery
                log.warning(
                    "agenda: cannot claim %s: %s; %s",
                    ", ".join(f"item {item.item_id}" for item in items),
                    _one_line(error),
                    "delivering without a claim"
                    if offline
                    else f"it waits, retrying in {CLAIM_RETRY_S} s",
                )
                state = (_MINE, 0) if offline else (_RETRY, now_us + CLAIM_RETRY_S * US_PER_S)
                with self._lock:
                    for item in items:
                        self._claims[_key(item)] = state
                return
            with self._lock:
                for item, outcome in zip(items, outcomes, strict=True):
                    if outcome is None:  # removed elsewhere
                        self._claims.pop(_key(item), None)
                        self._index.drop(item.item_id)
                        continue
                    if outcome == _THEIRS and self._claims.get(_key(item), ("", 0))[0] != _THEIRS:
                        self.claims_lost += 1
                    self._claims[_key(item)] = (outcome, 0)

        return claim

    def _poll(self, now_us: int) -> Callable[[], None]:
        """A job that reads the items added since the last poll (or, now and then, the
        cursors of every item: items removed elsewhere go, cursors moved elsewhere are
        taken) and, on a reload, forgets claims long settled.

        It reads ids and cursors first and whole rows only of the items it does not
        have as stored, so a poll of an unchanged agenda reads a few numbers."""

        def poll() -> None:
            reload = self._reload_at_us is None or now_us >= self._reload_at_us
            try:
                if reload:
                    self._reload_at_us = now_us + RELOAD_S * US_PER_S
                self._sync(full=reload)
                if reload:
                    with self._io_lock, self._engine.begin() as connection:
                        before = from_us(now_us - CLAIMS_KEEP_S * US_PER_S)
                        connection.execute(delete(ClaimRow).where(ClaimRow.fire_time < before))
                with self._lock:
                    self._advance(now_us, down=False)
            except SQLAlchemyError as error:
                log.warning("agenda: cannot read new items: %s", _one_line(error))

        return poll

    def _sync(self, full: bool) -> None:
        """Bring the index in line with the stored cursors: of every item (``full``: the
        items not stored any more are forgotten), or of the newest ones. A cursor behind
        this robot's is left (its misses of users it did not see are not written: the
        robot that next sees the user loads that cursor and writes them)."""
        items: Any = ItemRow.__table__
        query = select(items.c.id, items.c.next_fire).where(items.c.next_fire.is_not(None))
        if not full:
            query = query.where(items.c.id > self._high_id - POLL_OVERLAP)
        with self._io_lock:
            with self._engine.connect() as connection:
                cursors = {int(row.id): to_us(row.next_fire) for row in connection.execute(query)}
            with self._lock:
                queued = {record.item_id for record in self._queue}
                entries = self._index.entries
                wanted = [
                    item_id
                    for item_id, cursor in cursors.items()
                    if item_id not in queued
                    and ((entry := entries.get(item_id)) is None or entry.cursor_us < cursor)
                ]
            rows: list[ItemRow] = []
            if wanted:
                with self._sessions() as session:
                    rows = list(session.scalars(select(ItemRow).where(ItemRow.id.in_(wanted))))
            with self._lock:  # still under _io_lock: no item is added meanwhile
                self._apply_rows(rows, None, drop=False)
                if full:
                    for item_id in [i for i in self._index.entries if i not in cursors]:
                        self._index.drop(item_id)
                    self._forget_claims()

    def delivered(self, item: DueItem, now: datetime) -> None:
        """``item`` was started or spoken: log it and schedule its next occurrence.

        The agenda moves on at once, so the occurrence is never returned again. The
        record is journaled (one fsync'd line) before this returns and written to the
        database afterwards, off the tick; if the database is unavailable it is written
        later, also after a crash (the next start replays the journal).
        """
        fire_us = to_us(item.fire_time)
        now_us = to_us(now)
        with self._lock:
            cursor = self._index.next_after_delivery(item.item_id, fire_us)
            stored = self._index.entries[item.item_id].item
            self._index.delivered(item.item_id, cursor)
            self._claims.pop((item.item_id, fire_us), None)
            entry = _delivery_entry(stored, fire_us, now_us, cursor)
            entry["claimed_by"] = self.claimer
            self._enqueue([entry])
        self._offload(self._flush_or_retry(now_us))

    def _flush_or_retry(self, now_us: int) -> Callable[[], None]:
        """A job that flushes the queue; if the database fails, due() retries it later."""

        def flush() -> None:
            try:
                self._flush()
            except AgendaError as error:
                log.warning("%s; retrying in %s s", error, RETRY_AFTER_S)
                with self._lock:
                    if self._queue:
                        self._flush_at_us = now_us + RETRY_AFTER_S * US_PER_S

        return flush

    # ------------------------------------------------------------------ the log

    def missed_log(self, user_id: str | None) -> list[Occurrence]:
        """What was missed (runs of occurrences), oldest first; every user for None."""
        return self.history(user_id, Outcome.MISSED)

    def history(self, user_id: str | None, outcome: Outcome | None = None) -> list[Occurrence]:
        """Deliveries and misses, oldest first."""
        self._flush()
        query = select(OccurrenceRow).order_by(OccurrenceRow.fire_time, OccurrenceRow.id)
        if user_id is not None:
            query = query.where(OccurrenceRow.user_id == user_id)
        if outcome is not None:
            query = query.where(OccurrenceRow.outcome == str(outcome))
        with self._sessions() as session:
            return [_occurrence(row) for row in session.scalars(query)]

    # ------------------------------------------------------------------ privacy

    def export_user(self, user_id: str) -> dict[str, list[dict[str, Any]]]:
        """The user's items, their delivery log and the robots' claims of their
        occurrences, as stored (``dms users export``)."""
        self._flush()
        with self._sessions() as session:
            data = USER_DATA.export_user(session, user_id)
        return data or {"items": [], "log": [], "claims": []}

    def erase_user(self, user_id: str) -> None:
        """Delete the user's items and log, and forget their items here.

        :meth:`memory.ProfileStore.erase` deletes the same rows with the profile; this
        is for the process that holds the agenda's index (the daemon).
        """
        self._flush()
        with self._io_lock:
            try:
                with self._sessions.begin() as session:
                    USER_DATA.erase_user(session, user_id)
            except SQLAlchemyError as error:
                raise AgendaError(
                    f"cannot erase the agenda of {user_id}: {_one_line(error)}"
                ) from None
            with self._lock:
                for item_id in self._index.user_items(user_id):
                    self._index.drop(item_id)

    # ------------------------------------------------------------------ internals

    def _advance(self, now_us: int, down: bool) -> None:
        runs = self._index.advance(now_us, down)
        if runs and not self._unseen_misses:
            runs = [run for run in runs if self._saw(run)]
        if runs:
            self._enqueue([_miss_entry(run) for run in runs])
            if self._flush_at_us is None:
                self._flush_at_us = now_us + FLUSH_AFTER_S * US_PER_S
            self._forget_claims()

    def _saw(self, run: MissedRun) -> bool:
        """``_lock`` held: whether this robot saw the run's user since it fell due."""
        due_us = run.first_us - run.item.lead_s * US_PER_S
        return self._seen.get(run.item.user_id, -1) >= due_us

    def _forget_claims(self) -> None:
        """``_lock`` held: drop what we know of claims of occurrences no longer open."""
        entries = self._index.entries
        for key in [
            key
            for key in self._claims
            if (entry := entries.get(key[0])) is None or entry.cursor_us != key[1]
        ]:
            del self._claims[key]

    def _flush(self) -> None:
        """Write queued misses and deliveries, each with its item's new cursor.

        The database is written without the index's lock: the tick can go on meanwhile
        (what it queues then waits for the next flush). Never call it holding ``_lock``.
        """
        with self._io_lock:
            with self._lock:
                records = list(self._queue)
                if not records:
                    self._flush_at_us = None
                    return
            try:
                with self._engine.begin() as connection:
                    gone = _write(connection, [record.entry for record in records])
            except SQLAlchemyError as error:
                raise AgendaError(f"cannot write the agenda's log: {_one_line(error)}") from None
            with self._lock:
                del self._queue[: len(records)]
                for item_id in gone:  # removed or erased by another process: forget it here
                    self._index.drop(item_id)
                if not self._queue:
                    self._flush_at_us = None
            journaled = sum(record.journaled for record in records)
            with self._journal_lock:
                if journaled and self._journal is not None:
                    self._journal.done(journaled)

    def _load(self, user_id: str | None) -> None:
        """Bring the index in line with the database, for one user or everyone.

        Reads without the index's lock, then updates the index under it.
        """
        query = select(ItemRow).where(ItemRow.next_fire.is_not(None))
        if user_id is not None:
            query = query.where(ItemRow.user_id == user_id)
        with self._io_lock, self._sessions() as session:
            rows = list(session.scalars(query))
        with self._lock:
            self._apply_rows(rows, user_id)

    def _apply_rows(self, rows: Sequence[ItemRow], user_id: str | None, drop: bool = True) -> None:
        """The index after reading ``rows`` (``_lock`` held); with ``drop``, the items
        of ``user_id`` (everyone's for None) that are not in ``rows`` are forgotten.

        An item with a record still queued keeps its cursor here: the row is older.
        """
        queued = {record.item_id for record in self._queue}
        seen: set[int] = set()
        for row in rows:
            seen.add(row.id)
            self._high_id = max(self._high_id, row.id)
            known = self._index.entries.get(row.id)
            if known is not None and row.id in queued:
                continue
            if (
                known is not None
                and row.next_fire is not None
                and known.cursor_us == to_us(row.next_fire)
            ):
                continue
            try:
                item = _item(row)
                schedule = self._schedule(item.schedule, item.spec, item.tz, row.anchor)
            except AgendaError as error:
                problem = f"agenda item {row.id} cannot be loaded: {error}"
                if problem not in self.problems:
                    self.problems.append(problem)
                    log.warning("%s", problem)
                continue
            self._index.put(self._entry(item, schedule))
        self._forget_claims()
        if not drop:
            return
        stale = (
            self._index.user_items(user_id) if user_id is not None else list(self._index.entries)
        )
        for item_id in stale:
            if item_id not in seen:
                self._index.drop(item_id)

    def _entry(self, item: AgendaItem, schedule: Schedule) -> Entry:
        assert item.next_fire is not None
        return Entry(
            item=item,
            schedule=schedule,
            cursor_us=to_us(item.next_fire),
            lead_us=item.lead_s * US_PER_S,
            grace_us=item.grace_s * US_PER_S,
        )

    def _schedule(self, kind: str, spec: str, tz: str, anchor: datetime | None) -> Schedule:
        key = (kind, spec, tz, anchor)
        schedule = self._schedules.get(key)
        if schedule is None:
            try:
                schedule_kind = ScheduleKind(kind)
            except ValueError:
                raise AgendaError(f"unknown schedule {kind!r}") from None
            schedule = build(schedule_kind, spec, tz, anchor)
            self._schedules[key] = schedule
        return schedule

    def _validate(self, spec: ItemSpec, now: datetime) -> tuple[ItemRow, Schedule]:
        """The row to store for ``spec``, or AgendaError naming what is wrong."""
        if now.tzinfo is None:
            raise AgendaError("now must be timezone-aware")
        user_id = spec.user_id
        try:
            if check_identifier(user_id, "user_id") != user_id:
                raise InvalidIdentifier("user_id: has white space around it")
        except InvalidIdentifier as error:
            raise AgendaError(f"invalid user id {user_id!r:.80}: {error}") from None
        activity, text = spec.activity, spec.text
        if spec.kind == "event":
            if not activity:
                raise AgendaError("an event needs an activity")
            if activity not in ACTIVITIES:
                raise AgendaError(
                    f"unknown activity {activity!r} (one of: {', '.join(ACTIVITIES)})"
                )
            if text is not None:
                raise AgendaError("an event runs an activity and has no text")
        else:
            if activity is not None:
                raise AgendaError("a reminder has a text, not an activity")
            text = (text or "").strip()
            if not text:
                raise AgendaError("a reminder needs a text")
            if len(text) > MAX_TEXT:
                raise AgendaError(f"a reminder's text is at most {MAX_TEXT} characters")
        chosen = [name for name in ("at", "cron", "every") if getattr(spec, name) is not None]
        if len(chosen) != 1:
            raise AgendaError("give exactly one of at, cron or every")
        if not 0 <= spec.lead_s <= MAX_LEAD_S:
            raise AgendaError(f"lead_s must be between 0 and {MAX_LEAD_S}")
        if not 0 <= spec.grace_s <= MAX_GRACE_S:
            raise AgendaError(f"grace_s must be between 0 and {MAX_GRACE_S}")
        tz = zone(spec.tz)
        anchor: datetime | None = None
        if spec.at is not None:
            kind = ScheduleKind.AT
            fire = localize(spec.at, tz)
            if fire + timedelta(seconds=spec.grace_s) < now:
                raise AgendaError(f"{spec.at.isoformat()} is in the past")
            text_spec = fire.isoformat()
        elif spec.cron is not None:
            kind = ScheduleKind.CRON
            text_spec = " ".join(spec.cron.split())
        else:
            kind = ScheduleKind.EVERY
            every = spec.every
            assert every is not None
            if not 1 <= every <= MAX_EVERY_S:
                raise AgendaError(f"every must be between 1 and {MAX_EVERY_S} seconds")
            if spec.lead_s >= every:
                raise AgendaError("lead_s must be shorter than the interval")
            anchor = (now + timedelta(seconds=every)).astimezone(UTC)
            text_spec = str(every)
        schedule = build(kind, text_spec, spec.tz, anchor)
        first = schedule.first_at_or_after(now)
        if first is None:
            raise AgendaError(f"the cron expression {text_spec!r} never fires")
        if kind is ScheduleKind.CRON and spec.lead_s:
            _check_lead(schedule, first, spec.lead_s)
        if self._user_exists is not None and not self._user_exists(user_id):
            raise AgendaError(f"unknown user {user_id!r}")
        row = ItemRow(
            user_id=user_id,
            kind=spec.kind,
            activity=activity,
            text=text,
            schedule=str(kind),
            spec=text_spec,
            anchor=anchor,
            tz=spec.tz,
            priority=spec.priority,
            lead_s=spec.lead_s,
            grace_s=spec.grace_s,
            created_at=now.astimezone(UTC),
            next_fire=first.astimezone(UTC),
        )
        return row, schedule


def _check_lead(schedule: Schedule, first: datetime, lead_s: int) -> None:
    """A lead time must be shorter than the gaps between the next few occurrences."""
    fire: datetime | None = first
    for _ in range(8):
        assert fire is not None
        after = schedule.after(fire)
        if after is None:
            return
        if (after - fire).total_seconds() <= lead_s:
            raise AgendaError("lead_s must be shorter than the time between occurrences")
        fire = after


def _delivery_entry(
    item: AgendaItem, fire_us: int, recorded_us: int, cursor_us: int | None
) -> dict[str, Any]:
    """A delivery as the journal and :func:`_write` take it (JSON-able)."""
    return {
        "item_id": item.item_id,
        "user_id": item.user_id,
        "kind": str(item.kind),
        "what": _what(item),
        "outcome": str(Outcome.DELIVERED),
        "first_us": fire_us,
        "last_us": fire_us,
        "count": 1,
        "recorded_us": recorded_us,
        "reason": "",
        "cursor_us": cursor_us,
    }


def _miss_entry(run: MissedRun) -> dict[str, Any]:
    """A run of misses as the journal and :func:`_write` take it (JSON-able)."""
    item = run.item
    return {
        "item_id": item.item_id,
        "user_id": item.user_id,
        "kind": str(item.kind),
        "what": _what(item),
        "outcome": str(Outcome.MISSED),
        "first_us": run.first_us,
        "last_us": run.last_us,
        "count": run.count,
        "recorded_us": run.recorded_us,
        "reason": run.reason if run.exact else f"{run.reason} (at least this many)",
        "cursor_us": run.cursor_us,
    }


def _write(connection: Connection, entries: list[dict[str, Any]]) -> set[int]:
    """Log ``entries`` (deliveries and misses) and move their items' cursors, in bulk.

    An occurrence already logged (by another process, or before a crash: a journal
    replayed again) is skipped: ``(item_id, fire_time)`` is unique; but a delivery
    replaces a miss of the same occurrence (another robot of the fleet gave up on it
    while this one delivered it). A cursor only moves forward (a robot late with its
    writes does not move one back), so a replay ends where the original writes did.
    An entry of an item no longer stored (removed or erased by another process) is
    skipped: an erased user's log must not come back. Returns the ids of those items.
    A delivery also claims its occurrence (it may have been delivered without a claim
    while the database was away).
    """
    ids = {int(entry["item_id"]) for entry in entries}
    table = ItemRow.__table__
    stored = set(connection.scalars(select(table.c.id).where(table.c.id.in_(ids))))
    gone = ids - stored
    rows: list[dict[str, Any]] = []
    claims: list[dict[str, Any]] = []
    cursors: dict[int, int | None] = {}
    for entry in entries:
        item_id = int(entry["item_id"])
        if item_id in gone:
            continue
        rows.append(
            {
                "item_id": item_id,
                "user_id": entry["user_id"],
                "kind": entry["kind"],
                "what": entry["what"],
                "outcome": entry["outcome"],
                "fire_time": from_us(int(entry["first_us"])),
                "last_fire_time": from_us(int(entry["last_us"])),
                "count": int(entry["count"]),
                "recorded_at": from_us(int(entry["recorded_us"])),
                "reason": entry["reason"],
            }
        )
        if entry["outcome"] == str(Outcome.DELIVERED):
            claims.append(
                {
                    "item_id": item_id,
                    "fire_time": from_us(int(entry["first_us"])),
                    "user_id": entry["user_id"],
                    "claimed_by": str(entry.get("claimed_by", "unknown")),
                    "claimed_at": from_us(int(entry["recorded_us"])),
                }
            )
        cursor = entry["cursor_us"]
        if item_id in cursors and cursor is not None:
            known = cursors[item_id]
            cursor = None if known is None else max(known, int(cursor))
        cursors[item_id] = None if cursor is None else int(cursor)
    if not rows:
        return gone
    # Rows in key order: robots writing overlapping rows at once take their locks in one
    # order (PostgreSQL), so they wait for each other but never deadlock.
    rows.sort(key=lambda row: (row["item_id"], row["fire_time"]))
    _insert_new(connection, rows)
    if claims:
        claims.sort(key=lambda row: (row["item_id"], row["fire_time"]))
        _insert_claims(connection, claims)
    items: Any = ItemRow.__table__
    ordered = sorted(cursors.items())
    ends = [{"item": item_id} for item_id, cursor in ordered if cursor is None]
    moves = [
        {"item": item_id, "cursor": from_us(cursor)}
        for item_id, cursor in ordered
        if cursor is not None
    ]
    live = items.c.next_fire.is_not(None)
    if ends:
        connection.execute(
            update(items).where(items.c.id == bindparam("item"), live).values(next_fire=None),
            ends,
        )
    if moves:
        connection.execute(
            update(items)
            .where(
                items.c.id == bindparam("item"),
                live,
                items.c.next_fire < bindparam("cursor", type_=UtcDateTime()),
            )
            .values(next_fire=bindparam("cursor", type_=UtcDateTime())),
            moves,
        )
    return gone


def _insert_new(connection: Connection, rows: list[dict[str, Any]]) -> None:
    """Log the rows not logged yet; a delivery replaces a miss of the same occurrence."""
    table: Any = OccurrenceRow.__table__
    dialect = connection.dialect.name
    delivered = str(Outcome.DELIVERED)
    if dialect in ("sqlite", "postgresql"):
        module: Any = sqlite if dialect == "sqlite" else postgresql
        misses = [row for row in rows if row["outcome"] != delivered]
        deliveries = [row for row in rows if row["outcome"] == delivered]
        if misses:
            connection.execute(
                module.insert(table).on_conflict_do_nothing(
                    index_elements=["item_id", "fire_time"]
                ),
                misses,
            )
        if deliveries:
            statement = module.insert(table)
            replaced = ("outcome", "last_fire_time", "count", "recorded_at", "reason", "what")
            connection.execute(
                statement.on_conflict_do_update(
                    index_elements=["item_id", "fire_time"],
                    set_={name: statement.excluded[name] for name in replaced},
                    where=table.c.outcome != delivered,
                ),
                deliveries,
            )
        return
    for row in rows:
        try:
            with connection.begin_nested():
                connection.execute(insert(table), row)
        except IntegrityError:
            log.warning("agenda item %s at %s was already logged", row["item_id"], row["fire_time"])


def _insert_claims(connection: Connection, rows: list[dict[str, Any]]) -> None:
    table: Any = ClaimRow.__table__
    dialect = connection.dialect.name
    if dialect in ("sqlite", "postgresql"):
        module: Any = sqlite if dialect == "sqlite" else postgresql
        connection.execute(
            module.insert(table).on_conflict_do_nothing(index_elements=["item_id", "fire_time"]),
            rows,
        )
        return
    for row in rows:
        try:
            with connection.begin_nested():
                connection.execute(insert(table), row)
        except IntegrityError:
            pass


def _claim(connection: Connection, item: DueItem, claimer: str, now_us: int) -> str | None:
    """Claim one occurrence in the database: ``_MINE`` when this claimer has it (now or
    from before), ``_THEIRS`` when another one does, None when the item is gone."""
    items: Any = ItemRow.__table__
    if connection.scalar(select(items.c.id).where(items.c.id == item.item_id)) is None:
        return None
    table: Any = ClaimRow.__table__
    fire = item.fire_time
    row = {
        "item_id": item.item_id,
        "fire_time": fire,
        "user_id": item.user_id,
        "claimed_by": claimer,
        "claimed_at": from_us(now_us),
    }
    dialect = connection.dialect.name
    if dialect in ("sqlite", "postgresql"):
        module: Any = sqlite if dialect == "sqlite" else postgresql
        inserted = (
            connection.execute(
                module.insert(table)
                .values(row)
                .on_conflict_do_nothing(index_elements=["item_id", "fire_time"])
                .returning(table.c.item_id)
            ).first()
            is not None
        )
    else:
        try:
            with connection.begin_nested():
                connection.execute(insert(table).values(row))
            inserted = True
        except IntegrityError:
            inserted = False
    if inserted:
        return _MINE
    owner = connection.scalar(
        select(table.c.claimed_by).where(table.c.item_id == item.item_id, table.c.fire_time == fire)
    )
    return _MINE if owner == claimer else _THEIRS


def _key(item: DueItem) -> tuple[int, int]:
    return (item.item_id, to_us(item.fire_time))


def _what(item: AgendaItem) -> str:
    """The reminder's text or the event's activity, for the log."""
    if item.kind is ItemKind.REMINDER and item.text:
        return item.text
    return item.activity or ""


def _item(row: ItemRow) -> AgendaItem:
    try:
        kind, priority = ItemKind(row.kind), Priority(row.priority)
    except ValueError as error:
        raise AgendaError(str(error)) from None
    return AgendaItem(
        item_id=row.id,
        user_id=row.user_id,
        kind=kind,
        activity=row.activity,
        text=row.text,
        schedule=row.schedule,
        spec=row.spec,
        tz=row.tz,
        priority=priority,
        lead_s=row.lead_s,
        grace_s=row.grace_s,
        created_at=row.created_at,
        next_fire=row.next_fire,
    )


def _occurrence(row: OccurrenceRow) -> Occurrence:
    return Occurrence(
        item_id=row.item_id,
        user_id=row.user_id,
        kind=ItemKind(row.kind),
        what=row.what,
        outcome=Outcome(row.outcome),
        fire_time=row.fire_time,
        last_fire_time=row.last_fire_time,
        count=row.count,
        recorded_at=row.recorded_at,
        reason=row.reason,
    )


class _AgendaUserData:
    """The agenda's part of ``dms users export|erase``: the user's items and log.

    Registered with the profile store, which calls it inside its own transaction. A
    database without the agenda's tables (a store made by ``memory`` alone) has none.
    """

    name = "agenda"

    def export_user(self, session: Session, user_id: str) -> dict[str, list[dict[str, Any]]] | None:
        """Every column of the user's items and log rows, oldest first."""
        if not _has_tables(session):
            return None
        return {
            "items": [_stored(row) for row in session.scalars(_of(ItemRow, user_id))],
            "log": [_stored(row) for row in session.scalars(_of(OccurrenceRow, user_id))],
            "claims": [
                _stored(row)
                for row in session.scalars(
                    select(ClaimRow)
                    .where(ClaimRow.user_id == user_id)
                    .order_by(ClaimRow.fire_time, ClaimRow.item_id)
                )
            ],
        }

    def erase_user(self, session: Session, user_id: str) -> None:
        """Delete the user's log and items."""
        if not _has_tables(session):
            return
        session.execute(delete(ClaimRow).where(ClaimRow.user_id == user_id))
        session.execute(delete(OccurrenceRow).where(OccurrenceRow.user_id == user_id))
        session.execute(delete(ItemRow).where(ItemRow.user_id == user_id))


def _has_tables(session: Session) -> bool:
    names = {ItemRow.__tablename__, OccurrenceRow.__tablename__, ClaimRow.__tablename__}
    return names <= set(inspect(session.connection()).get_table_names())


def _of(model: type[ItemRow] | type[OccurrenceRow], user_id: str) -> Any:
    return select(model).where(model.user_id == user_id).order_by(model.id)


def _stored(row: ItemRow | OccurrenceRow | ClaimRow) -> dict[str, Any]:
    """A row as stored, times in ISO 8601."""
    out: dict[str, Any] = {}
    for column in row.__table__.columns:
        value = getattr(row, column.key)
        out[column.key] = value.isoformat() if isinstance(value, datetime) else value
    return out


USER_DATA = _AgendaUserData()
register_user_data(USER_DATA)
