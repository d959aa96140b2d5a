"""The agenda's log writes: deliveries and misses on their way to the database.

A delivery or a run of misses becomes a JSON-able *entry* (:func:`delivery_entry`,
:func:`miss_entry`), is submitted to the agenda's :class:`memory.writer.Writer` (the
same background writer as the profile store's, :data:`CODEC` says how an entry is
spooled) and written in bulk by :func:`write_records`. The writer's spool is the
agenda's journal (:func:`journal_path`): with ``journal=True`` an entry is in it,
fsync'd, before it is submitted, so it survives a kill -9, and the next start replays
it before it computes what is due.

:class:`Background` runs the agenda's other database work (claims, polls, loads) off
the tick. This module knows nothing of the agenda's index or locks;
:class:`agenda.service.Agenda` decides when to queue and when to flush.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from concurrent.futures import wait as wait_for
from pathlib import Path
from typing import Any

from sqlalchemy import Connection, bindparam, insert, make_url, select, update
from sqlalchemy.exc import IntegrityError

from agenda.index import MissedRun
from agenda.items import AgendaItem, ItemKind, Outcome
from agenda.models import ClaimRow, ItemRow, OccurrenceRow, UtcDateTime
from agenda.schedule import from_us
from memory.db import as_url, dialect_module, side_file
from memory.writer import Codec

log = logging.getLogger(__name__)

JOURNAL_SUFFIX = "agenda-spool"
"""The journal's file: ``<db file>.agenda-spool``, or in the state folder for a server."""
QUARANTINE_SUFFIX = "agenda-quarantine"
"""Where records the database refused for good are kept, beside the journal."""

_FIELDS: dict[str, type | tuple[type, ...]] = {
    "item_id": int,
    "user_id": str,
    "kind": str,
    "what": str,
    "outcome": str,
    "first_us": int,
    "last_us": int,
    "count": int,
    "recorded_us": int,
    "reason": str,
    "cursor_us": (int, type(None)),
}


def journal_path(url: str, owner: str | None = None) -> Path | None:
    """Where the agenda's journal for ``url`` lives (``owner``'s own: a robot id); None
    for an in-memory database."""
    return _side(url, JOURNAL_SUFFIX, owner)


def quarantine_path(url: str, owner: str | None = None) -> Path | None:
    """Where the agenda keeps the records the database refused for good; None for an
    in-memory database (they are in the log)."""
    return _side(url, QUARANTINE_SUFFIX, owner)


def _side(url: str, suffix: str, owner: str | None) -> Path | None:
    parsed = make_url(as_url(url))  # a plain file path (``--db dms.db``) too
    if parsed.get_backend_name() == "sqlite" and parsed.database in (None, "", ":memory:"):
        return None
    return side_file(url, suffix, owner)


def readable(entry: dict[str, Any]) -> bool:
    """Whether a journaled entry has a record's keys and their types (others are kept aside)."""
    return all(
        key in entry and isinstance(entry[key], kind) and not isinstance(entry[key], bool)
        for key, kind in _FIELDS.items()
    )


def label(entry: dict[str, Any]) -> str:
    """A record in a report line."""
    return f"the {entry.get('outcome')} record of agenda item {entry.get('item_id')}"


CODEC: Codec[dict[str, Any]] = Codec(dict, dict, readable, label)
"""Entries are spooled as they are."""


class Background:
    """One thread that runs the agenda's database work in order, or none (jobs run at
    once in the caller's thread: the command line, the simulator)."""

    def __init__(self, enabled: bool) -> None:
        self._jobs = (
            ThreadPoolExecutor(max_workers=1, thread_name_prefix="dms-agenda") if enabled else None
        )

    def offload(self, job: Callable[[], None]) -> Future[None] | None:
        """Run ``job`` on the background thread, or at once without one.

        Returns the background job's future (None when it ran at once or was refused)."""
        if self._jobs is None:
            job()
            return None
        try:
            return self._jobs.submit(_guarded, job)
        except RuntimeError:  # shut down: the caller is closing, close() flushes
            log.warning("agenda: closing, %s left to close()", getattr(job, "__name__", job))
            return None

    def wait_idle(self, timeout: float) -> bool:
        """Wait until the jobs queued so far are done; False if ``timeout`` passed first."""
        if self._jobs is None:
            return True
        try:
            future = self._jobs.submit(lambda: None)
        except RuntimeError:
            return True
        done, _ = wait_for([future], timeout=timeout)
        return bool(done)

    def shutdown(self) -> None:
        """Finish the jobs queued so far; later ones are refused."""
        if self._jobs is not None:
            self._jobs.shutdown(wait=True)


def _guarded(job: Callable[[], None]) -> None:
    try:
        job()
    except Exception:  # a background job must not die silently; the next one retries
        log.exception("agenda: background database work failed")


def delivery_entry(
    item: AgendaItem, fire_us: int, recorded_us: int, cursor_us: int | None
) -> dict[str, Any]:
    """A delivery as the journal and :func:`write_records` take it (JSON-able)."""
    return {
        "item_id": item.item_id,
        "user_id": item.user_id,
        "kind": str(item.kind),
        "what": what(item),
        "outcome": str(Outcome.DELIVERED),
        "first_us": fire_us,
        "last_us": fire_us,
        "count": 1,
        "recorded_us": recorded_us,
        "reason": "",
        "cursor_us": cursor_us,
    }


def miss_entry(run: MissedRun) -> dict[str, Any]:
    """A run of misses as the journal and :func:`write_records` take it (JSON-able)."""
    item = run.item
    return {
        "item_id": item.item_id,
        "user_id": item.user_id,
        "kind": str(item.kind),
        "what": what(item),
        "outcome": str(Outcome.MISSED),
        "first_us": run.first_us,
        "last_us": run.last_us,
        "count": run.count,
        "recorded_us": run.recorded_us,
        "reason": run.reason if run.exact else f"{run.reason} (at least this many)",
        "cursor_us": run.cursor_us,
    }


def write_records(connection: Connection, entries: list[dict[str, Any]]) -> set[int]:
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
        module: Any = dialect_module(dialect)
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
        module: Any = dialect_module(dialect)
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


def what(item: AgendaItem) -> str:
    """The reminder's text or the event's activity, for the log."""
    if item.kind is ItemKind.REMINDER and item.text:
        return item.text
    return item.activity or ""
