"""What the simulation needs from the agenda and the profile store, in one place.

Scenarios add agenda items and store profile fields; long-term runs give each user a
daily reminder. These helpers keep the simulation's use of those packages' APIs here.
"""

from __future__ import annotations

from datetime import datetime
from typing import TYPE_CHECKING, Any

from sim.errors import SimError

if TYPE_CHECKING:
    from dms.assembly import Stack
    from sim.scenario import AgendaSpec


def add_agenda_item(agenda: Any, spec: AgendaSpec, when: datetime, now: datetime) -> None:
    """Add the reminder or event ``spec`` for ``spec.user``, due at ``when``."""
    raise SimError("the agenda cannot be scripted yet")


def daily_reminder(agenda: Any, user_id: str, hour: int, minute: int, now: datetime) -> None:
    """A reminder for ``user_id`` every day at ``hour:minute`` UTC (long-term runs)."""
    raise SimError("the agenda cannot be scripted yet")


def seed_profile(stack: Stack, user_id: str, fields: dict[str, Any], now: datetime) -> None:
    """Store ``fields`` in ``user_id``'s profile (created if new) before a run."""
    raise SimError("profiles cannot be seeded yet")
