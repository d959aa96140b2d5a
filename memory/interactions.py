"""Interaction events: what a person did in a session, in the form a participant model learns from.

The daemon writes one row per event as the session runs (``dms.interactions`` makes
them from the tick's inputs and decisions); ``dms sessions export --events`` reads them
back as one table, and ``dms sim fit`` estimates the simulated participants' inputs
from it. The events of a session, in their order (``seq``):

- ``arrived``: the session began (the person was seen present and ready);
- ``offered``: the robot offered a choice or asked (``offer_kind``: ``menu`` of
  activities, general ``question``, ``rating`` of an activity, ``confirm``: "continue or
  stop?"); ``offer`` numbers it in the session;
- ``input``: the person spoke (``channel`` ``voice``, ``confidence`` the recogniser's,
  ``understood`` whether the daemon took it), tapped the screen (``screen``), touched
  the robot (``touch``, ``value`` the part) or a program asked (``request``, ``by`` who);
  while an offer is open, a spoken or tapped input names it (``offer``) and its
  ``delay_s`` counts from the offer;
- ``unanswered``: an offer closed without any spoken or tapped input;
- ``started``, ``completed``, ``cancelled``, ``failed``, ``paused``, ``resumed``: the
  daemon's decisions about an activity (``by``: who chose or who stopped it, ``detail``
  the decision's reason);
- ``left``: the session ended (``detail``: why).

Every value is bounded (:func:`check_event`): a malformed event is refused in one line
naming its field, and the write that carries it is quarantined, never half applied.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from datetime import UTC, datetime
from typing import Any

from sqlalchemy import Connection, insert, select

from memory.errors import ProfileError
from memory.models import InteractionEventRow, SessionRow
from memory.rows import check_time

EVENTS = frozenset(
    {
        "arrived",
        "offered",
        "input",
        "unanswered",
        "started",
        "completed",
        "cancelled",
        "failed",
        "paused",
        "resumed",
        "left",
    }
)
"""Every event kind (see the module docstring)."""
OFFER_KINDS = frozenset({"menu", "question", "rating", "confirm"})
CHANNELS = frozenset({"voice", "screen", "touch", "request"})
MAX_EVENTS = 500
"""Events in one write: a tick makes a handful; more is a fault, refused whole."""

_TEXT = {"value": 200, "activity": 50, "by": 64, "detail": 200}
"""The text columns and their lengths (longer text is cut by the maker, refused here)."""

COLUMNS: tuple[str, ...] = (
    "session",
    "user",
    "seq",
    "time",
    "t_s",
    "event",
    "offer",
    "offer_kind",
    "channel",
    "value",
    "confidence",
    "understood",
    "delay_s",
    "activity",
    "by",
    "detail",
)
"""The exported table's columns, in order (docs/memory.md describes each)."""


def check_event(raw: Any) -> dict[str, Any]:
    """One event as a row's values; ProfileError naming the field that is wrong."""
    if not isinstance(raw, Mapping):
        raise ProfileError(f"interaction event: must be an object (got {raw!r:.60})")
    unknown = set(raw) - {"at", "seq", "event", "offer", "offer_kind", "channel", "confidence"}
    unknown -= {"understood", "delay_s", *_TEXT}
    if unknown:
        raise ProfileError(f"interaction event: unknown field {sorted(unknown)[0]!r:.60}")
    event = raw.get("event")
    if event not in EVENTS:
        raise ProfileError(f"interaction event: event must be one of {sorted(EVENTS)}")
    row: dict[str, Any] = {"event": event, "at": check_time("interaction event: at", raw.get("at"))}
    row["seq"] = _count("seq", raw.get("seq"), required=True)
    row["offer"] = _count("offer", raw.get("offer"))
    row["offer_kind"] = _one_of("offer_kind", raw.get("offer_kind"), OFFER_KINDS)
    row["channel"] = _one_of("channel", raw.get("channel"), CHANNELS)
    row["confidence"] = _number("confidence", raw.get("confidence"), 0.0, 1.0)
    row["delay_s"] = _number("delay_s", raw.get("delay_s"), 0.0, 1e7)
    understood = raw.get("understood")
    if understood is not None and not isinstance(understood, bool):
        raise ProfileError("interaction event: understood must be true, false or null")
    row["understood"] = understood
    for name, length in _TEXT.items():
        value = raw.get(name)
        if value is not None and (not isinstance(value, str) or len(value) > length):
            raise ProfileError(
                f"interaction event: {name} must be a string of at most {length} characters"
            )
        row[name] = value
    return row


def _count(name: str, value: Any, required: bool = False) -> int | None:
    if value is None and not required:
        return None
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value < 2**31:
        raise ProfileError(f"interaction event: {name} must be a whole number >= 0")
    return value


def _one_of(name: str, value: Any, allowed: frozenset[str]) -> str | None:
    if value is not None and value not in allowed:
        raise ProfileError(f"interaction event: {name} must be one of {sorted(allowed)} or null")
    return value  # type: ignore[no-any-return]


def _number(name: str, value: Any, low: float, high: float) -> float | None:
    if value is None:
        return None
    if (
        isinstance(value, bool)
        or not isinstance(value, int | float)
        or not math.isfinite(value)
        or not low <= value <= high
    ):
        raise ProfileError(f"interaction event: {name} must be a number in [{low:g}, {high:g}]")
    return float(value)


def check_events(events: Any) -> list[dict[str, Any]]:
    """A write's events, each checked; ProfileError for the first that is wrong."""
    if not isinstance(events, Sequence) or isinstance(events, str | bytes):
        raise ProfileError("interaction events: must be a list of objects")
    if len(events) > MAX_EVENTS:
        raise ProfileError(f"interaction events: at most {MAX_EVENTS} in one write")
    return [check_event(event) for event in events]


def insert_events(
    connection: Connection, user_id: str, session_id: int | None, rows: list[dict[str, Any]]
) -> None:
    """Append checked events (:func:`check_events`) to the session's record."""
    if rows:
        connection.execute(
            insert(InteractionEventRow),
            [{**row, "user_id": user_id, "session_id": session_id} for row in rows],
        )


def read_events(connection: Connection, since: datetime | None = None) -> list[dict[str, Any]]:
    """Every event of the sessions started at or after ``since``, as rows of
    :data:`COLUMNS`: by session (oldest first), then in their order. ``t_s`` counts from
    the session's start; an event whose session was never stored has none."""
    events = InteractionEventRow.__table__
    sessions = SessionRow.__table__
    query = (
        select(events, sessions.c.started_at.label("session_started"))
        .select_from(events.outerjoin(sessions, events.c.session_id == sessions.c.id))
        .order_by(
            sessions.c.started_at.is_(None),
            sessions.c.started_at,
            events.c.session_id,
            events.c.user_id,
            events.c.seq,
            events.c.id,
        )
    )
    if since is not None:
        query = query.where(sessions.c.started_at >= since)
    out: list[dict[str, Any]] = []
    for row in connection.execute(query).mappings():
        at: datetime = _utc(row["at"])
        started = row["session_started"]
        t_s = None if started is None else round((at - _utc(started)).total_seconds(), 3)
        out.append(
            {
                "session": row["session_id"],
                "user": row["user_id"],
                "seq": row["seq"],
                "time": at.isoformat(),
                "t_s": t_s,
                **{name: row[name] for name in COLUMNS[5:]},
            }
        )
    return out


def _utc(value: datetime) -> datetime:
    """A time read back without its zone is UTC (as :class:`memory.models.UtcDateTime`)."""
    return value.replace(tzinfo=UTC) if value.tzinfo is None else value.astimezone(UTC)
