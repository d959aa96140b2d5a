"""The agenda: each user's events and reminders, on time, across restarts.

As in the paper's User-adaptive system, an *event* runs an activity at a time and a
*reminder* is a short message the General manager speaks while the current activity
pauses. Items live in the daemon's database as data; APScheduler's triggers compute
their fire times against the daemon's clock. The controller asks :meth:`Agenda.due`
on every tick and reports :meth:`Agenda.delivered`; what its user could not receive
within the grace time is logged as missed, never dropped and never run twice.
"""

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
from agenda.service import Agenda

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
