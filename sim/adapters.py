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

REMINDER_GRACE_S = 2 * 3600
"""A long-term run's daily reminder waits this long for its user."""


def add_agenda_item(agenda: Any, spec: AgendaSpec, when: datetime, now: datetime) -> None:
    """Add the reminder or event ``spec`` for ``spec.user``, due at ``when``."""
    from agenda import AgendaError, ItemSpec

    data: dict[str, Any] = {
        "user_id": spec.user,
        "kind": spec.kind,
        "at": when,
        "priority": spec.priority,
    }
    if spec.kind == "reminder":
        data["text"] = spec.text or "This is a reminder."
    else:
        data["activity"] = spec.activity
        if spec.text is not None:
            raise SimError("an event runs an activity and has no text")
    try:
        agenda.add(ItemSpec.from_data(data), now)
    except AgendaError as error:
        raise SimError(str(error)) from None


def daily_reminder(agenda: Any, user_id: str, hour: int, minute: int, now: datetime) -> None:
    """A reminder for ``user_id`` every day at ``hour:minute`` UTC (long-term runs)."""
    from agenda import AgendaError, ItemSpec

    spec = {
        "user_id": user_id,
        "kind": "reminder",
        "text": "It is time for your medicine.",
        "cron": f"{minute} {hour} * * *",
        "grace_s": REMINDER_GRACE_S,
    }
    try:
        agenda.add(ItemSpec.from_data(spec), now)
    except AgendaError as error:
        raise SimError(f"daily reminder for {user_id}: {error}") from None


def ensure_user(stack: Stack, user_id: str, now: datetime) -> None:
    """Create ``user_id``'s profile if it does not exist (the agenda only takes known users)."""
    if stack.store is not None:
        stack.store.get_or_create(user_id, now)


def seed_profile(stack: Stack, user_id: str, fields: dict[str, Any], now: datetime) -> None:
    """Store ``fields`` in ``user_id``'s profile (created if new) before a run."""
    from memory import ProfileError

    if stack.store is None:
        raise SimError("profiles: this scenario runs without memory")
    try:
        stack.store.get_or_create(user_id, now)
        stack.store.update(user_id, now, **fields)
    except (ProfileError, TypeError, ValueError) as error:
        raise SimError(f"profiles.{user_id}: {error}") from None
