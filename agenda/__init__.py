"""The agenda: each user's events and reminders, on time, across restarts.

As in the paper's User-adaptive system, an *event* runs an activity at a time and a
*reminder* is a short message the General manager speaks while the current activity
pauses. Items live in the daemon's database as data; APScheduler's triggers compute
their fire times against the daemon's clock. The controller asks :meth:`Agenda.due`
on every tick and reports :meth:`Agenda.delivered`; what its user could not receive
within the grace time is logged as missed, never dropped and never run twice.
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any

from agenda.errors import AgendaError, AgendaNotFound
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

if TYPE_CHECKING:
    from agenda.service import Agenda


def __getattr__(name: str) -> Any:
    """:class:`Agenda` is imported on first use: its database layer (SQLAlchemy's ORM)
    is the largest part of the daemon's imports, and the daemon opens the agenda only
    once it is ready (its items and the controller's view of them load without it)."""
    if name != "Agenda":
        raise AttributeError(f"module 'agenda' has no attribute {name!r}")
    value = import_module("agenda.service").Agenda
    globals()[name] = value
    return value


__all__ = [
    "Agenda",
    "AgendaError",
    "AgendaItem",
    "AgendaNotFound",
    "DueItem",
    "ItemKind",
    "ItemSpec",
    "Occurrence",
    "Outcome",
    "Priority",
    "UpcomingItem",
]
