"""The agenda's values: what a caller asks for and what it gets back.

:class:`ItemSpec` is the request to add an item (checked for types by pydantic,
then for meaning by :meth:`agenda.Agenda.add`). :class:`AgendaItem` is a stored
item, :class:`DueItem` one occurrence that is due now, :class:`UpcomingItem` an
item with its next fire time, :class:`Occurrence` one line of the delivery log.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from datetime import datetime
from enum import StrEnum
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, StrictInt, ValidationError

from agenda.errors import AgendaError
from agenda.schedule import zone
from dms.kernel.clock import iso


class ItemKind(StrEnum):
    """What an item does when it falls due."""

    EVENT = "event"
    """Runs an activity (cognitive stimulation every Monday at 10:00)."""
    REMINDER = "reminder"
    """A short spoken message; the running activity pauses and then resumes."""


class Priority(StrEnum):
    """How an item treats the activity that runs when it falls due."""

    HIGH = "high"
    """Cancels the running activity (the paper's cancel reason (c))."""
    NORMAL = "normal"
    """Waits until the running activity ends."""


PRIORITY_RANK = {Priority.HIGH: 0, Priority.NORMAL: 1}
"""Sort key: high priority first."""


class Outcome(StrEnum):
    """What became of one occurrence."""

    DELIVERED = "delivered"
    MISSED = "missed"


class ItemSpec(BaseModel):
    """A request to add an item: exactly one of ``at``, ``cron``, ``every``.

    ``at`` without a time zone is a wall time in ``tz``. ``lead_s``: announce this
    many seconds before the fire time. ``grace_s``: how long after the fire time the
    item still waits for its user before it is recorded as missed.
    """

    model_config = ConfigDict(frozen=True, extra="forbid", defer_build=True)

    user_id: str
    kind: Literal["event", "reminder"]
    activity: str | None = None
    text: str | None = None
    at: datetime | None = None
    cron: str | None = None
    every: StrictInt | None = None
    tz: str = "UTC"
    priority: Literal["high", "normal"] = "normal"
    lead_s: StrictInt = 0
    grace_s: StrictInt = 600

    @classmethod
    def from_data(cls, data: Mapping[str, Any]) -> ItemSpec:
        """Validate ``data`` (a JSON object, CLI flags); AgendaError names the bad field."""
        try:
            return cls.model_validate(dict(data))
        except ValidationError as error:
            first = error.errors()[0]
            where = ".".join(str(part) for part in first["loc"]) or "item"
            raise AgendaError(f"{where}: {first['msg']}") from None


@dataclass(frozen=True, slots=True)
class AgendaItem:
    """A stored item as the agenda keeps it."""

    item_id: int
    user_id: str
    kind: ItemKind
    activity: str | None
    text: str | None
    schedule: str
    """``at``, ``cron`` or ``every``."""
    spec: str
    """The ISO UTC instant, the crontab expression or the seconds."""
    tz: str
    priority: Priority
    lead_s: int
    grace_s: int
    created_at: datetime
    next_fire: datetime | None
    """The first occurrence not yet delivered or missed; None when none is left."""

    def describe(self) -> str:
        """The schedule in words, for lists and logs."""
        if self.schedule == "every":
            return f"every {self.spec} s"
        return f"{self.schedule} {self.spec}"

    def to_json(self) -> dict[str, Any]:
        return {
            "id": self.item_id,
            "user_id": self.user_id,
            "kind": str(self.kind),
            "activity": self.activity,
            "text": self.text,
            "schedule": self.schedule,
            "spec": self.spec,
            "tz": self.tz,
            "priority": str(self.priority),
            "lead_s": self.lead_s,
            "grace_s": self.grace_s,
            "next_fire": iso(self.next_fire) if self.next_fire else None,
        }


@dataclass(frozen=True, slots=True)
class DueItem:
    """One occurrence of an item, due now for its user (from ``due_at`` on)."""

    item_id: int
    user_id: str
    kind: ItemKind
    activity: str | None
    text: str | None
    priority: Priority
    fire_time: datetime
    """When the item is scheduled (UTC)."""
    due_at: datetime
    """``fire_time - lead``: when it may be announced."""


@dataclass(frozen=True, slots=True)
class UpcomingItem:
    """An item with its next occurrence, for lists and the Zenoh query."""

    item_id: int
    user_id: str
    kind: ItemKind
    activity: str | None
    text: str | None
    priority: Priority
    schedule: str
    tz: str
    next_fire: datetime
    due_at: datetime
    lead_s: int
    grace_s: int
    waiting: bool
    """Due already and waiting for its user (within its grace time)."""

    def to_json(self) -> dict[str, Any]:
        """The JSON shape of docs/agenda.md."""
        return {
            "id": self.item_id,
            "user_id": self.user_id,
            "kind": str(self.kind),
            "activity": self.activity,
            "text": self.text,
            "priority": str(self.priority),
            "schedule": self.schedule,
            "tz": self.tz,
            "next_fire": iso(self.next_fire),
            "next_fire_local": self.next_fire.astimezone(zone(self.tz)).isoformat(),
            "due_at": iso(self.due_at),
            "lead_s": self.lead_s,
            "grace_s": self.grace_s,
            "waiting": self.waiting,
        }


@dataclass(frozen=True, slots=True)
class Occurrence:
    """One line of the delivery log: an occurrence delivered, or a run of missed ones."""

    item_id: int
    user_id: str
    kind: ItemKind
    what: str
    """The reminder's text or the event's activity."""
    outcome: Outcome
    fire_time: datetime
    last_fire_time: datetime
    """The last occurrence of a run of missed ones (``fire_time`` for one)."""
    count: int
    recorded_at: datetime
    reason: str

    def to_json(self) -> dict[str, Any]:
        return {
            "id": self.item_id,
            "user_id": self.user_id,
            "kind": str(self.kind),
            "what": self.what,
            "outcome": str(self.outcome),
            "fire_time": iso(self.fire_time),
            "last_fire_time": iso(self.last_fire_time),
            "count": self.count,
            "recorded_at": iso(self.recorded_at),
            "reason": self.reason,
        }
