"""The agenda in memory: who has what due when, checked on every tick without SQL.

Each item has a *cursor*, its first occurrence not yet delivered or missed. The
cursor is in one of two heaps:

- ``_due``: (due time, item) for cursors not yet due (``due = fire - lead``);
- ``_expiry``: (expiry, item) for cursors that are due and wait for their user.

An occurrence may be delivered while ``due <= now <= fire + grace`` and before the
next occurrence falls due; after that it is missed. Missed occurrences in a row
(a long absence, the daemon down) make one :class:`MissedRun`. The index decides;
:class:`agenda.service.Agenda` writes the decisions to the database.

A tick with nothing to do costs two heap peeks and a dictionary lookup. Entries of
removed or moved items stay in the heaps and are dropped when they come up.
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass, field

from agenda.errors import AgendaError, AgendaNotFound
from agenda.items import PRIORITY_RANK, AgendaItem, DueItem, UpcomingItem
from agenda.schedule import NEVER_US, Schedule, from_us, to_us

US_PER_S = 1_000_000
CATCH_UP_LIMIT = 10_000
"""Missed occurrences counted one by one before the rest of a run is skipped at once."""

SUPERSEDED = "the next occurrence fell due before it was delivered"
AWAY = "its user was not there within the grace time"
DOWN = "it fell due while the daemon was down and the grace time passed"


@dataclass(slots=True)
class Entry:
    """An item in the index with the state of its cursor."""

    item: AgendaItem
    schedule: Schedule
    cursor_us: int
    lead_us: int
    grace_us: int
    waiting: bool = False
    next_us: int | None = None
    """The occurrence after the cursor, known once the cursor is due."""
    expire_us: int = NEVER_US
    due_item: DueItem | None = None

    @classmethod
    def of(cls, item: AgendaItem, schedule: Schedule) -> Entry:
        """A stored item with its cursor at its stored next fire time."""
        assert item.next_fire is not None
        return cls(
            item=item,
            schedule=schedule,
            cursor_us=to_us(item.next_fire),
            lead_us=item.lead_s * US_PER_S,
            grace_us=item.grace_s * US_PER_S,
        )

    @property
    def due_us(self) -> int:
        return self.cursor_us - self.lead_us

    def expiry(self, fire_us: int, next_us: int | None) -> int:
        """The first instant at which the occurrence at ``fire_us`` is missed."""
        ends = fire_us + self.grace_us + 1
        if next_us is not None:
            ends = min(ends, next_us - self.lead_us)
        return ends


@dataclass(frozen=True, slots=True)
class MissedRun:
    """Consecutive missed occurrences of one item, and where its cursor went."""

    item: AgendaItem
    first_us: int
    last_us: int
    count: int
    exact: bool
    """False when the run was too long to count and the rest was skipped."""
    reason: str
    recorded_us: int
    cursor_us: int | None
    """The item's cursor after the run; None when no occurrence is left."""


@dataclass(slots=True)
class AgendaIndex:
    """Next fire times of every loaded item, and what waits for whom."""

    entries: dict[int, Entry] = field(default_factory=dict)
    _due: list[tuple[int, int, int]] = field(default_factory=list)
    _expiry: list[tuple[int, int, int]] = field(default_factory=list)
    _waiting: dict[str, dict[int, DueItem]] = field(default_factory=dict)
    _sorted: dict[str, list[DueItem]] = field(default_factory=dict)

    # ------------------------------------------------------------------ loading

    def put(self, entry: Entry) -> None:
        """Add or replace an item (its cursor is not due yet, as far as we know)."""
        self.drop(entry.item.item_id)
        self.entries[entry.item.item_id] = entry
        heapq.heappush(self._due, (entry.due_us, entry.item.item_id, entry.cursor_us))

    def drop(self, item_id: int) -> bool:
        """Forget an item; its heap entries die when they come up."""
        entry = self.entries.pop(item_id, None)
        if entry is None:
            return False
        if entry.waiting:
            self._unwait(entry)
        return True

    def user_items(self, user_id: str) -> list[int]:
        return [i for i, e in self.entries.items() if e.item.user_id == user_id]

    # ------------------------------------------------------------------ per tick

    def has_work(self, now_us: int) -> bool:
        """Whether :meth:`advance` has anything to do at ``now_us``."""
        due, expiry = self._due, self._expiry
        return bool((due and due[0][0] <= now_us) or (expiry and expiry[0][0] <= now_us))

    def advance(self, now_us: int, down: bool = False) -> list[MissedRun]:
        """Move cursors to ``now_us``: due ones wait for their user, late ones are missed.

        ``down``: the misses happened while the daemon was not running (for the log).
        """
        runs: list[MissedRun] = []
        while self._expiry and self._expiry[0][0] <= now_us:
            _, item_id, fire_us = heapq.heappop(self._expiry)
            entry = self.entries.get(item_id)
            if entry is None or not entry.waiting or entry.cursor_us != fire_us:
                continue
            self._unwait(entry)
            self._miss_from(entry, entry.next_us, now_us, down, runs)
        while self._due and self._due[0][0] <= now_us:
            _, item_id, fire_us = heapq.heappop(self._due)
            entry = self.entries.get(item_id)
            if entry is None or entry.waiting or entry.cursor_us != fire_us:
                continue
            self._fall_due(entry, now_us, down, runs)
        return runs

    def waiting_for(self, user_id: str) -> list[DueItem]:
        """What is due for ``user_id`` now: high priority first, then by fire time."""
        cached = self._sorted.get(user_id)
        if cached is None:
            waiting = self._waiting.get(user_id)
            if not waiting:
                return []
            cached = sorted(waiting.values(), key=_due_order)
            self._sorted[user_id] = cached
        return list(cached)

    def all_waiting(self) -> list[DueItem]:
        return sorted((d for w in self._waiting.values() for d in w.values()), key=_due_order)

    # ------------------------------------------------------------------ delivery

    def next_after_delivery(self, item_id: int, fire_us: int) -> int | None:
        """The cursor after delivering the occurrence at ``fire_us``; checks it may be."""
        entry = self.entries.get(item_id)
        if entry is None:
            raise AgendaNotFound(f"no agenda item {item_id} is loaded")
        if entry.cursor_us != fire_us:
            raise AgendaError(
                f"agenda item {item_id} has no open occurrence at {from_us(fire_us).isoformat()} "
                "(already delivered or missed)"
            )
        if entry.waiting:
            return entry.next_us
        return entry.schedule.after_us(fire_us)

    def delivered(self, item_id: int, next_us: int | None) -> None:
        """Move the cursor past a delivered occurrence."""
        entry = self.entries[item_id]
        if entry.waiting:
            self._unwait(entry)
        if next_us is None:
            del self.entries[item_id]
            return
        entry.cursor_us = next_us
        heapq.heappush(self._due, (entry.due_us, item_id, next_us))

    # ------------------------------------------------------------------ listing

    def upcoming(self, user_id: str | None, now_us: int, limit: int) -> list[UpcomingItem]:
        """Each item's live occurrence at ``now_us`` (without recording anything)."""
        result: list[UpcomingItem] = []
        for entry in self.entries.values():
            if user_id is not None and entry.item.user_id != user_id:
                continue
            fire_us = self._live(entry, now_us)
            if fire_us is None:
                continue
            item = entry.item
            result.append(
                UpcomingItem(
                    item_id=item.item_id,
                    user_id=item.user_id,
                    kind=item.kind,
                    activity=item.activity,
                    text=item.text,
                    priority=item.priority,
                    schedule=item.describe(),
                    tz=item.tz,
                    next_fire=from_us(fire_us),
                    due_at=from_us(fire_us - entry.lead_us),
                    lead_s=item.lead_s,
                    grace_s=item.grace_s,
                    waiting=fire_us - entry.lead_us <= now_us,
                )
            )
        result.sort(key=lambda u: (u.next_fire, PRIORITY_RANK[u.priority], u.item_id))
        return result[:limit]

    def _live(self, entry: Entry, now_us: int) -> int | None:
        """The occurrence of ``entry`` that is open at ``now_us``, or the next one."""
        if entry.waiting and now_us < entry.expire_us:
            return entry.cursor_us
        if not entry.waiting and now_us < entry.due_us:
            return entry.cursor_us
        fire: int | None = entry.cursor_us
        steps = 0
        while fire is not None:
            after = entry.schedule.after_us(fire)
            if now_us < entry.expiry(fire, after):
                return fire
            fire = after
            steps += 1
            if steps >= CATCH_UP_LIMIT:
                return entry.schedule.first_us(now_us + entry.lead_us + 1)
        return None

    # ------------------------------------------------------------------ internals

    def _fall_due(self, entry: Entry, now_us: int, down: bool, runs: list[MissedRun]) -> None:
        next_us = entry.schedule.after_us(entry.cursor_us)
        expire_us = entry.expiry(entry.cursor_us, next_us)
        if now_us >= expire_us:
            self._miss_from(entry, next_us, now_us, down, runs)
            return
        entry.waiting = True
        entry.next_us = next_us
        entry.expire_us = expire_us
        item = entry.item
        due = DueItem(
            item_id=item.item_id,
            user_id=item.user_id,
            kind=item.kind,
            activity=item.activity,
            text=item.text,
            priority=item.priority,
            fire_time=from_us(entry.cursor_us),
            due_at=from_us(entry.due_us),
        )
        entry.due_item = due
        self._waiting.setdefault(item.user_id, {})[item.item_id] = due
        self._sorted.pop(item.user_id, None)
        heapq.heappush(self._expiry, (expire_us, item.item_id, entry.cursor_us))

    def _miss_from(
        self,
        entry: Entry,
        next_us: int | None,
        now_us: int,
        down: bool,
        runs: list[MissedRun],
    ) -> None:
        """Record the cursor and every later occurrence already past as one missed run."""
        first = last = entry.cursor_us
        superseded = next_us is not None and next_us - entry.lead_us < first + entry.grace_us + 1
        reason = DOWN if down else (SUPERSEDED if superseded else AWAY)
        count, exact = 1, True
        fire = next_us
        while fire is not None:
            if count >= CATCH_UP_LIMIT:
                fire = entry.schedule.first_us(now_us + entry.lead_us + 1)
                exact = False
                break
            after = entry.schedule.after_us(fire)
            if now_us < entry.expiry(fire, after):
                break
            last, count, fire = fire, count + 1, after
        runs.append(MissedRun(entry.item, first, last, count, exact, reason, now_us, fire))
        if fire is None:
            del self.entries[entry.item.item_id]
            return
        entry.cursor_us = fire
        if entry.due_us <= now_us:
            self._fall_due(entry, now_us, down, runs)
        else:
            heapq.heappush(self._due, (entry.due_us, entry.item.item_id, fire))

    def _unwait(self, entry: Entry) -> None:
        entry.waiting = False
        entry.due_item = None
        user = entry.item.user_id
        waiting = self._waiting.get(user)
        if waiting is not None:
            waiting.pop(entry.item.item_id, None)
            if not waiting:
                del self._waiting[user]
        self._sorted.pop(user, None)


def _due_order(item: DueItem) -> tuple[int, object, int]:
    return (PRIORITY_RANK[item.priority], item.fire_time, item.item_id)
