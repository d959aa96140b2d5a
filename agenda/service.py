"""The agenda: events and reminders per user, stored in the daemon's database.

Over 600 lines: every method that takes the agenda's two locks is here, so that their
order can be checked in one file.

The controller calls :meth:`Agenda.due` on every tick; it answers from the
in-memory :class:`agenda.index.AgendaIndex`, without SQL. Deliveries are written at
once (:meth:`Agenda.delivered`); misses are queued and written within
:data:`FLUSH_AFTER_S` (and before any read of the log), which keeps the tick cheap.
A miss that is lost in a crash is found again on restart, because the item's cursor
in the database moves only when its occurrence is logged.

Deliveries and misses go through the same background writer as the profile store's
(:class:`memory.writer.Writer`: queue, backoff, spool, quarantine, reports once per
outage). Its spool is the agenda's journal (the daemon's, on by default with
``background=True``: :func:`agenda.writer.journal_path`): every delivery and miss is in
it, ``fsync``'d, before the call that records it returns, and the writer marks it done
once the database has it. A kill -9 while the write waits (another process holds
SQLite's lock, PostgreSQL is away) loses nothing: the next start replays the journal into
the database before it computes what is due, so an occurrence delivered before the crash
is never delivered again. A record the database refuses for good is quarantined.

With ``background=True`` (the daemon) the calls from the tick (:meth:`Agenda.due`,
:meth:`Agenda.delivered`, :meth:`Agenda.user_perceived`) never touch the database: the
writer's thread writes the records, one background thread runs the reads and claims, in
order. Database I/O never holds the index's lock (``_lock``), only ``_io_lock``, which
serializes it; so a locked or absent database never stalls the tick. Lock order: the
writer's, then ``_io_lock``, then ``_lock``, never the other way (the writer takes
nothing of the agenda while it holds its own lock).

Several robots share one agenda (docs/fleet.md). An occurrence is claimed before
:meth:`Agenda.due` returns it (:mod:`agenda.claims`), so of two robots that see the user
in the same second only one delivers it. Without the database no claim can be made: on a
server database the occurrence waits (it is claimed when the database is back, or
missed), on a SQLite file, which only robots on one machine share, it is delivered anyway
(``offline_delivery``). Items added elsewhere (another robot, the command line) are polled
for every :data:`POLL_S` of the caller's clock, and the whole agenda is reloaded every
:data:`RELOAD_S`.
"""

from __future__ import annotations

import logging
import os
import socket
import threading
import uuid
from collections.abc import Callable, Sequence
from concurrent.futures import wait as wait_for
from datetime import datetime
from pathlib import Path
from typing import Any

from sqlalchemy import Engine, delete, select
from sqlalchemy.exc import SQLAlchemyError
from sqlalchemy.orm import sessionmaker

from agenda import claims, writer
from agenda.claims import CLAIM_RETRY_S, CLAIM_WAIT_S, CLAIMS_KEEP_S, MINE, PENDING, RETRY, Claims
from agenda.errors import AgendaError, AgendaNotFound
from agenda.index import US_PER_S, AgendaIndex, Entry, MissedRun
from agenda.items import AgendaItem, DueItem, ItemSpec, Occurrence, Outcome, UpcomingItem
from agenda.models import ClaimRow, ItemRow, OccurrenceRow
from agenda.rows import Schedules, item_of, occurrence_of, prepare_schema, validate
from agenda.schedule import from_us, to_us
from agenda.seen import SeenUsers
from agenda.user_data import USER_DATA
from agenda.writer import journal_path
from memory.db import make_engine
from memory.errors import one_line
from memory.watch import sqlite_file
from memory.writer import REPLAY_BATCH, Writer, WriterHealth

log = logging.getLogger(__name__)

FLUSH_AFTER_S = 300
"""Longest time a recorded miss waits in memory before it is written."""
RETRY_AFTER_S = 5
BACKGROUND_BUSY_TIMEOUT_S = 1.0
"""SQLite lock wait of the background thread: it retries later rather than wait long."""
POLL_S = 10
"""Between reads of items added since the last one (by another robot, the command line)."""
POLL_OVERLAP = 100
"""Ids below the highest seen that a poll reads again (ids committed out of order)."""
RELOAD_S = 300
"""Between reloads of every item (items removed elsewhere, cursors moved elsewhere)."""

__all__ = [
    "CLAIMS_KEEP_S",
    "CLAIM_RETRY_S",
    "CLAIM_WAIT_S",
    "POLL_S",
    "Agenda",
    "journal_path",
]


class Agenda:
    """Every user's events and reminders; the controller's view of what is due."""

    def __init__(
        self,
        engine: Engine,
        *,
        claimer: str,
        user_exists: Callable[[str], bool] | None = None,
        background: bool = False,
        journaled: bool = False,
        offline_delivery: bool | None = None,
        poll_s: float | None = POLL_S,
        unseen_misses: bool | None = None,
    ) -> None:
        """The agenda's state in memory over ``engine``, empty and without its writer:
        :meth:`open` makes one, then reads the database into it (see there for the
        arguments). Nothing here touches the database or a file."""
        self.claimer = claimer
        self._engine = engine
        self._sessions = sessionmaker(engine, expire_on_commit=False)
        local = engine.dialect.name == "sqlite"
        self._offline_delivery = local if offline_delivery is None else offline_delivery
        self._unseen_misses = local if unseen_misses is None else unseen_misses
        self._journaled = journaled
        self._claims = Claims()
        self._seen = SeenUsers()
        """When this robot last saw each user (perceived, or present at ``due``)."""
        self._poll_us = None if poll_s is None else round(poll_s * US_PER_S)
        self._poll_at_us: int | None = None
        self._reload_at_us: int | None = None
        self._high_id = 0
        self._user_exists = user_exists
        # Lock order: _io_lock before _lock, never the other way. _lock guards the
        # in-memory state (index, queue, claims, seen users) and is held only briefly;
        # _io_lock serializes the database work, which never holds _lock, so a locked or
        # absent database never stalls the tick.
        self._lock = threading.RLock()
        self._io_lock = threading.Lock()
        self._background = writer.Background(background)
        self._index = AgendaIndex()
        self._flush_at_us: int | None = None
        """When the records waiting are written (without a writer thread: the caller's clock)."""
        self._schedules = Schedules()
        self.problems: list[str] = []
        """Stored items that could not be loaded (bad spec, unknown zone), one line each."""
        self._writer: Writer[dict[str, Any]]
        """Writes deliveries and misses; :meth:`open` gives it (it calls :meth:`_write`)."""

    @classmethod
    def open(
        cls,
        url: str,
        user_exists: Callable[[str], bool] | None = None,
        background: bool = False,
        journal: bool | None = None,
        claimer: str | None = None,
        offline_delivery: bool | None = None,
        poll_s: float | None = POLL_S,
        unseen_misses: bool | None = None,
        report: Callable[[str, str], None] | None = None,
        spool_dir: Path | None = None,
    ) -> Agenda:
        """Open the agenda at ``url``, replay its journal and load every item; AgendaError
        (one line) when the database cannot be opened or is not the agenda's.

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

        ``report``: where the writer's lines go (the daemon's ``dms/errors``; default: the
        log); ``spool_dir``: a folder on another filesystem for the journal when the one
        beside the database cannot be written.
        """
        try:
            engine = make_engine(url, BACKGROUND_BUSY_TIMEOUT_S if background else None)
        except (SQLAlchemyError, OSError) as error:
            raise AgendaError(f"cannot open the agenda at {url}: {one_line(error)}") from None
        journaled = background if journal is None else journal
        agenda = cls(
            engine,
            claimer=claimer or f"{socket.gethostname()}-{os.getpid()}-{uuid.uuid4().hex[:8]}",
            user_exists=user_exists,
            background=background,
            journaled=journaled,
            offline_delivery=offline_delivery,
            poll_s=poll_s,
            unseen_misses=unseen_misses,
        )
        agenda._writer = Writer(
            agenda._write,
            writer.CODEC,
            writer.journal_path(url, claimer) if journaled else None,
            writer.quarantine_path(url, claimer) if journaled else None,
            report or _log_report,
            name="agenda writer",
            report_key="agenda",
            threaded=background,
            inline=False,
            journal=journaled,
            batch=REPLAY_BATCH,
            spool_dir=spool_dir,
            database_file=sqlite_file(url) if background else None,
        )
        try:
            prepare_schema(engine)
            agenda._replay_journal()
            agenda._load(None)
            agenda._apply_queued()
        except (SQLAlchemyError, OSError) as error:
            agenda._abandon()
            raise AgendaError(f"cannot open the agenda at {url}: {one_line(error)}") from None
        except AgendaError:
            agenda._abandon()
            raise
        agenda._writer.start()
        return agenda

    def _abandon(self) -> None:
        """The agenda did not open: release what it holds."""
        self._writer.close()
        self._background.shutdown()
        self._engine.dispose()

    def _replay_journal(self) -> None:
        """At start: write what the journal holds (a crash's or an outage's), in order.

        Runs before the items are loaded, so their cursors already count these records.
        If the database will not take them now (another process holds its lock), they
        stay journaled, :meth:`_apply_queued` moves the cursors in memory, and the writer
        writes them later.
        """
        count = self._writer.pending
        if not count:
            return
        try:
            self._flush()
        except AgendaError as error:
            log.warning("%s; %d journaled record(s) kept for later", error, count)
            self._retry_later(0)
            return
        log.info("agenda: %d journaled record(s) replayed into the database", count)

    def _apply_queued(self) -> None:
        """Move the loaded items' cursors past the records still waiting (journal replay)."""
        with self._lock:
            for entry in self._writer.waiting():
                item_id = int(entry["item_id"])
                if item_id in self._index.entries:
                    cursor = entry["cursor_us"]
                    self._index.delivered(item_id, None if cursor is None else int(cursor))

    def _enqueue(self, entries: list[dict[str, Any]]) -> None:
        """Hand records to the writer (``_lock`` held: keeps the order); with a journal
        they are in it, fsync'd, when this returns (or, when no spool can be written,
        reported and kept in memory)."""
        self._writer.submit_all(entries)

    def _write(self, entries: list[dict[str, Any]]) -> list[None]:
        """The writer's apply: log ``entries`` in one transaction, and forget the items
        removed or erased by another process."""
        with self._io_lock:
            with self._engine.begin() as connection:
                gone = writer.write_records(connection, entries)
            with self._lock:
                for item_id in gone:
                    self._index.drop(item_id)
        return [None] * len(entries)

    def _waiting_items(self) -> set[int]:
        """The items with a record not yet in the database (their stored cursor is older)."""
        return {int(entry["item_id"]) for entry in self._writer.waiting()}

    def _retry_later(self, at_us: int) -> None:
        """Without a writer thread, flush again at ``at_us`` of the caller's clock (the
        thread retries by itself, with backoff)."""
        if not self._writer.threaded:
            with self._lock:
                self._flush_at_us = at_us

    @property
    def engine(self) -> Engine:
        """The agenda's database engine (the simulator sets its throw-away file's sync)."""
        return self._engine

    @property
    def health(self) -> WriterHealth:
        """Whether the agenda's records wait for the database, how many and why."""
        return self._writer.health

    @property
    def claims_lost(self) -> int:
        """Occurrences another robot claimed first."""
        return self._claims.lost

    def close(self) -> None:
        """Finish the background work, write what is queued and release the database.

        With a journal, what the database will not take now stays journaled for the next
        start (one log line says how much); without one, AgendaError.
        """
        self._background.shutdown()
        try:
            self._flush()
        except AgendaError as error:
            if not self._journaled:
                raise
            log.warning(
                "%s; %d agenda record(s) kept in the journal for the next start",
                error,
                self._writer.pending,
            )
        finally:
            self._writer.close()
            self._engine.dispose()

    # ------------------------------------------------------------------ management

    def add(self, spec: ItemSpec, now: datetime) -> AgendaItem:
        """Store a new item; AgendaError (one line, nothing stored) when it is invalid."""
        row, schedule = validate(spec, now, self._user_exists)
        with self._io_lock:
            try:
                with self._sessions.begin() as session:
                    session.add(row)
                    session.flush()
                    item = item_of(row)
            except SQLAlchemyError as error:
                raise AgendaError(f"cannot store the agenda item: {one_line(error)}") from None
            with self._lock:
                self._index.put(Entry.of(item, schedule))
                self._high_id = max(self._high_id, item.item_id)
            return item

    def get(self, item_id: int) -> AgendaItem:
        """The stored item ``item_id``; AgendaNotFound if there is none."""
        with self._sessions() as session:
            row = session.get(ItemRow, item_id)
            if row is None:
                raise AgendaNotFound(f"no agenda item {item_id}")
            return item_of(row)

    def remove(self, item_id: int) -> None:
        """Delete item ``item_id`` (its log stays); AgendaNotFound if there is none."""
        self._flush()
        with self._io_lock:
            try:
                with self._sessions.begin() as session:
                    deleted = session.execute(delete(ItemRow).where(ItemRow.id == item_id))
            except SQLAlchemyError as error:
                raise AgendaError(
                    f"cannot remove agenda item {item_id}: {one_line(error)}"
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
            self._seen.saw(user_id, to_us(now))

        def perceive() -> None:
            try:
                self._flush()
            except AgendaError as error:
                log.warning("%s; retrying in %s s", error, RETRY_AFTER_S)
            self._load(user_id)
            with self._lock:
                self._advance(to_us(now), down=False)

        self._background.offload(perceive)

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
            if not self._journaled:
                raise
            log.warning("%s; journaled, retrying in %s s", error, RETRY_AFTER_S)
            self._retry_later(to_us(now) + RETRY_AFTER_S * US_PER_S)
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
        self._writer.poll(now_us / US_PER_S)  # reports what opening the journal found
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
            if present_user is not None:
                self._seen.saw(present_user, now_us)
            waiting = [] if present_user is None else self._index.waiting_for(present_user)
            to_claim = [item for item in waiting if self._claims.needs_claim(item, now_us)]
            for item in to_claim:
                self._claims.set(item, PENDING)
        if flush:
            self._background.offload(self._flush_or_retry(now_us))
        if poll:
            self._background.offload(self._poll(now_us))
        if to_claim:
            future = self._background.offload(self._claim_job(to_claim, now_us))
            if future is not None:
                wait_for([future], timeout=CLAIM_WAIT_S)
        if not waiting:
            return []
        assert present_user is not None
        with self._lock:
            return [
                item for item in self._index.waiting_for(present_user) if self._claims.is_mine(item)
            ]

    def wait_idle(self, timeout: float) -> bool:
        """Wait until the background work queued so far is done and every record is
        written (tests, benchmarks)."""
        return self._background.wait_idle(timeout) and self._writer.wait_idle(timeout)

    def claim(self, item: DueItem, now: datetime) -> bool:
        """Claim one occurrence for this robot now, in the database; whether it is ours.

        What :meth:`due` does for each item it returns; True again for an occurrence
        this robot (this ``claimer``) claimed before, False once another robot has it.
        """
        now_us = to_us(now)
        self._claim_job([item], now_us)()
        with self._lock:
            return self._claims.is_mine(item)

    def _claim_job(self, items: list[DueItem], now_us: int) -> Callable[[], None]:
        """A job that claims ``items`` in one transaction and notes the outcomes."""

        def claim() -> None:
            try:
                with self._io_lock, self._engine.begin() as connection:
                    outcomes = [
                        claims.claim_occurrence(connection, item, self.claimer, now_us)
                        for item in items
                    ]
            except SQLAlchemyError as error:
                offline = self._offline_delivery
                log.warning(
                    "agenda: cannot claim %s: %s; %s",
                    ", ".join(f"item {item.item_id}" for item in items),
                    one_line(error),
                    "delivering without a claim"
                    if offline
                    else f"it waits, retrying in {CLAIM_RETRY_S} s",
                )
                state, retry_us = (
                    (MINE, 0) if offline else (RETRY, now_us + CLAIM_RETRY_S * US_PER_S)
                )
                with self._lock:
                    for item in items:
                        self._claims.set(item, state, retry_us)
                return
            with self._lock:
                for item, outcome in zip(items, outcomes, strict=True):
                    if outcome is None:  # removed elsewhere
                        self._claims.drop(claims.key(item))
                        self._index.drop(item.item_id)
                        continue
                    self._claims.note(item, outcome)

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
                log.warning("agenda: cannot read new items: %s", one_line(error))

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
                queued = self._waiting_items()
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
                    self._claims.forget_closed(self._index.entries)

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
            self._claims.drop((item.item_id, fire_us))
            entry = writer.delivery_entry(stored, fire_us, now_us, cursor)
            entry["claimed_by"] = self.claimer
            self._enqueue([entry])
        if not self._writer.threaded:
            self._background.offload(self._flush_or_retry(now_us))

    def _flush_or_retry(self, now_us: int) -> Callable[[], None]:
        """A job that flushes the queue; if the database fails, due() retries it later."""

        def flush() -> None:
            try:
                self._flush()
            except AgendaError as error:
                log.warning("%s; retrying in %s s", error, RETRY_AFTER_S)
                self._retry_later(now_us + RETRY_AFTER_S * US_PER_S)

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
            return [occurrence_of(row) for row in session.scalars(query)]

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
                    f"cannot erase the agenda of {user_id}: {one_line(error)}"
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
            self._enqueue([writer.miss_entry(run) for run in runs])
            if self._flush_at_us is None and not self._writer.threaded:
                self._flush_at_us = now_us + FLUSH_AFTER_S * US_PER_S
            self._claims.forget_closed(self._index.entries)

    def _saw(self, run: MissedRun) -> bool:
        """``_lock`` held: whether this robot saw the run's user since it fell due."""
        due_us = run.first_us - run.item.lead_s * US_PER_S
        seen_us = self._seen.last(run.item.user_id)
        return seen_us is not None and seen_us >= due_us

    def _flush(self) -> None:
        """Write the records waiting (misses and deliveries, each with its item's new
        cursor) now, in this thread; AgendaError when the database will not take them.

        The database is written without the index's lock: the tick can go on meanwhile
        (what it queues then waits for the next flush). Never call it holding ``_lock``.
        """
        failure = self._writer.flush()
        if failure is not None:
            raise AgendaError(f"cannot write the agenda's log: {one_line(failure)}")
        with self._lock:
            if not self._writer.pending:
                self._flush_at_us = None

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
        queued = self._waiting_items()
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
                item = item_of(row)
                schedule = self._schedules.of(row)
            except AgendaError as error:
                problem = f"agenda item {row.id} cannot be loaded: {error}"
                if problem not in self.problems:
                    self.problems.append(problem)
                    log.warning("%s", problem)
                continue
            self._index.put(Entry.of(item, schedule))
        self._claims.forget_closed(self._index.entries)
        if not drop:
            return
        stale = (
            self._index.user_items(user_id) if user_id is not None else list(self._index.entries)
        )
        for item_id in stale:
            if item_id not in seen:
                self._index.drop(item_id)


def _log_report(key: str, line: str) -> None:
    """Where the writer's lines go without a daemon (the command line, tests): the log."""
    log.warning("%s: %s", key, line)
