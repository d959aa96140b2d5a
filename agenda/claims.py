"""Claims across robots: which robot of a fleet delivers an occurrence.

An occurrence is *claimed* before :meth:`agenda.service.Agenda.due` returns it: a row in
``agenda_claims`` keyed by (item, fire time), inserted with ``ON CONFLICT DO NOTHING``,
so of two robots that see the user in the same second one gets it and the other never
returns it (it records it missed at the end of the grace time if nobody delivered it; a
delivery wins over such a miss in the log). :func:`claim_occurrence` makes the claim in
the database; :class:`Claims` is what one robot knows of its own.
"""

from __future__ import annotations

from typing import Any

from sqlalchemy import Connection, insert, select
from sqlalchemy.exc import IntegrityError

from agenda.index import Entry
from agenda.items import DueItem
from agenda.models import ClaimRow, ItemRow
from agenda.rows import MAX_GRACE_S, MAX_LEAD_S
from agenda.schedule import from_us, to_us
from memory.db import dialect_module

CLAIM_WAIT_S = 0.05
"""How long :meth:`agenda.service.Agenda.due` waits for a claim made off the tick
(``background``): enough for a healthy database, so the item comes out in the same
tick; else it comes out of a later one."""
CLAIM_RETRY_S = 2
"""Between claims of one occurrence while the database cannot be reached."""
CLAIMS_KEEP_S = MAX_GRACE_S + MAX_LEAD_S + 86400
"""How long a claim is kept after its fire time: past it the occurrence is settled."""

MINE, THEIRS, PENDING, RETRY = "mine", "theirs", "pending", "retry"
"""A claim's state as this robot knows it: this robot has it, another one has it, the
claim is being made, the database could not be reached (retried later)."""

Key = tuple[int, int]
"""An occurrence: (item id, fire time in microseconds)."""


def key(item: DueItem) -> Key:
    """The occurrence ``item`` is."""
    return (item.item_id, to_us(item.fire_time))


class Claims:
    """What this robot knows of its claims: occurrence -> (state, retry time).

    Not thread-safe: the agenda calls it with its index lock held.
    """

    def __init__(self) -> None:
        self._known: dict[Key, tuple[str, int]] = {}
        self.lost = 0
        """Occurrences another robot claimed first."""

    def needs_claim(self, item: DueItem, now_us: int) -> bool:
        """Whether ``item`` must be claimed (again) now."""
        state, retry_us = self._known.get(key(item), ("", 0))
        return state == "" or (state == RETRY and now_us >= retry_us)

    def is_mine(self, item: DueItem) -> bool:
        return self._known.get(key(item), ("", 0))[0] == MINE

    def set(self, item: DueItem, state: str, retry_us: int = 0) -> None:
        self._known[key(item)] = (state, retry_us)

    def note(self, item: DueItem, outcome: str) -> None:
        """The database's answer to a claim of ``item`` (:data:`MINE` or :data:`THEIRS`)."""
        if outcome == THEIRS and self._known.get(key(item), ("", 0))[0] != THEIRS:
            self.lost += 1
        self._known[key(item)] = (outcome, 0)

    def drop(self, occurrence: Key) -> None:
        """Forget the claim of ``occurrence`` (delivered, or its item is gone)."""
        self._known.pop(occurrence, None)

    def forget_closed(self, entries: dict[int, Entry]) -> None:
        """Forget the claims of occurrences no longer open: their item is not in
        ``entries`` (the index's) or its cursor has moved past them."""
        for occurrence in [
            occurrence
            for occurrence in self._known
            if (entry := entries.get(occurrence[0])) is None or entry.cursor_us != occurrence[1]
        ]:
            del self._known[occurrence]


def claim_occurrence(
    connection: Connection, item: DueItem, claimer: str, now_us: int
) -> str | None:
    """Claim one occurrence in the database: ``MINE`` when this claimer has it (now or
    from before), ``THEIRS`` when another one does, None when the item is gone."""
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
        module: Any = dialect_module(dialect)
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
        return MINE
    owner = connection.scalar(
        select(table.c.claimed_by).where(table.c.item_id == item.item_id, table.c.fire_time == fire)
    )
    return MINE if owner == claimer else THEIRS
