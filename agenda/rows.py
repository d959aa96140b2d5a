"""The agenda's rows: checking an item before it is stored, reading rows back as values.

:func:`validate` turns an :class:`agenda.items.ItemSpec` into the row to store (or an
:class:`AgendaError` naming what is wrong); :func:`item_of` and :func:`occurrence_of`
read stored rows back; :func:`prepare_schema` creates or checks the tables at open.
"""

from __future__ import annotations

from collections.abc import Callable
from datetime import UTC, datetime, timedelta

from sqlalchemy import Engine
from sqlalchemy.exc import SQLAlchemyError

from agenda import migrations
from agenda.errors import AgendaError
from agenda.items import AgendaItem, ItemKind, ItemSpec, Occurrence, Outcome, Priority
from agenda.models import ItemRow, OccurrenceRow
from agenda.schedule import MAX_EVERY_S, Schedule, ScheduleKind, build, localize, zone
from dms.kernel.activity_names import ACTIVITIES, current
from dms.kernel.ids import InvalidIdentifier, check_identifier

MAX_LEAD_S = 86400
MAX_GRACE_S = 7 * 86400
MAX_TEXT = 500


def prepare_schema(engine: Engine) -> None:
    """At open: create the agenda's tables in a new database, or check that they are
    at the revision this code needs and all there (AgendaError otherwise)."""
    with engine.connect() as connection:
        new = migrations.needs_tables(connection)
    if new:
        try:
            migrations.upgrade_engine(engine)
        except SQLAlchemyError:
            # Another process may have created it at the same time.
            with engine.connect() as connection:
                if migrations.current(connection) != migrations.head():
                    raise


def validate(
    spec: ItemSpec, now: datetime, user_exists: Callable[[str], bool] | None
) -> tuple[ItemRow, Schedule]:
    """The row to store for ``spec`` and its schedule, or AgendaError naming what is wrong.

    ``user_exists``: checks that the item's user has a profile (None: any user).
    """
    if now.tzinfo is None:
        raise AgendaError("now must be timezone-aware")
    user_id = spec.user_id
    try:
        if check_identifier(user_id, "user_id") != user_id:
            raise InvalidIdentifier("user_id: has white space around it")
    except InvalidIdentifier as error:
        raise AgendaError(f"invalid user id {user_id!r:.80}: {error}") from None
    activity, text = spec.activity, spec.text
    if spec.kind == "event":
        if not activity:
            raise AgendaError("an event needs an activity")
        if activity not in ACTIVITIES:
            raise AgendaError(current().unknown(activity))
        if text is not None:
            raise AgendaError("an event runs an activity and has no text")
    else:
        if activity is not None:
            raise AgendaError("a reminder has a text, not an activity")
        text = (text or "").strip()
        if not text:
            raise AgendaError("a reminder needs a text")
        if len(text) > MAX_TEXT:
            raise AgendaError(f"a reminder's text is at most {MAX_TEXT} characters")
    chosen = [name for name in ("at", "cron", "every") if getattr(spec, name) is not None]
    if len(chosen) != 1:
        raise AgendaError("give exactly one of at, cron or every")
    if not 0 <= spec.lead_s <= MAX_LEAD_S:
        raise AgendaError(f"lead_s must be between 0 and {MAX_LEAD_S}")
    if not 0 <= spec.grace_s <= MAX_GRACE_S:
        raise AgendaError(f"grace_s must be between 0 and {MAX_GRACE_S}")
    tz = zone(spec.tz)
    anchor: datetime | None = None
    if spec.at is not None:
        kind = ScheduleKind.AT
        fire = localize(spec.at, tz)
        if fire + timedelta(seconds=spec.grace_s) < now:
            raise AgendaError(f"{spec.at.isoformat()} is in the past")
        text_spec = fire.isoformat()
    elif spec.cron is not None:
        kind = ScheduleKind.CRON
        text_spec = " ".join(spec.cron.split())
    else:
        kind = ScheduleKind.EVERY
        every = spec.every
        assert every is not None
        if not 1 <= every <= MAX_EVERY_S:
            raise AgendaError(f"every must be between 1 and {MAX_EVERY_S} seconds")
        if spec.lead_s >= every:
            raise AgendaError("lead_s must be shorter than the interval")
        anchor = (now + timedelta(seconds=every)).astimezone(UTC)
        text_spec = str(every)
    schedule = build(kind, text_spec, spec.tz, anchor)
    first = schedule.first_at_or_after(now)
    if first is None:
        raise AgendaError(f"the cron expression {text_spec!r} never fires")
    if kind is ScheduleKind.CRON and spec.lead_s:
        _check_lead(schedule, first, spec.lead_s)
    if user_exists is not None and not user_exists(user_id):
        raise AgendaError(f"unknown user {user_id!r}")
    row = ItemRow(
        user_id=user_id,
        kind=spec.kind,
        activity=activity,
        text=text,
        schedule=str(kind),
        spec=text_spec,
        anchor=anchor,
        tz=spec.tz,
        priority=spec.priority,
        lead_s=spec.lead_s,
        grace_s=spec.grace_s,
        created_at=now.astimezone(UTC),
        next_fire=first.astimezone(UTC),
    )
    return row, schedule


def _check_lead(schedule: Schedule, first: datetime, lead_s: int) -> None:
    """A lead time must be shorter than the gaps between the next few occurrences."""
    fire: datetime | None = first
    for _ in range(8):
        assert fire is not None
        after = schedule.after(fire)
        if after is None:
            return
        if (after - fire).total_seconds() <= lead_s:
            raise AgendaError("lead_s must be shorter than the time between occurrences")
        fire = after


class Schedules:
    """The schedules of stored items, each built once: many items share one (the same
    cron line for many users), and the index rebuilds an item's entry whenever its
    stored cursor moves."""

    def __init__(self) -> None:
        self._built: dict[tuple[str, str, str, datetime | None], Schedule] = {}

    def of(self, row: ItemRow) -> Schedule:
        """The schedule of ``row``; AgendaError for a kind this code does not know."""
        key = (row.schedule, row.spec, row.tz, row.anchor)
        schedule = self._built.get(key)
        if schedule is None:
            try:
                kind = ScheduleKind(row.schedule)
            except ValueError:
                raise AgendaError(f"unknown schedule {row.schedule!r}") from None
            schedule = build(kind, row.spec, row.tz, row.anchor)
            self._built[key] = schedule
        return schedule


def item_of(row: ItemRow) -> AgendaItem:
    """A stored item as a value; AgendaError for a kind or priority this code does not know."""
    try:
        kind, priority = ItemKind(row.kind), Priority(row.priority)
    except ValueError as error:
        raise AgendaError(str(error)) from None
    return AgendaItem(
        item_id=row.id,
        user_id=row.user_id,
        kind=kind,
        activity=row.activity,
        text=row.text,
        schedule=row.schedule,
        spec=row.spec,
        tz=row.tz,
        priority=priority,
        lead_s=row.lead_s,
        grace_s=row.grace_s,
        created_at=row.created_at,
        next_fire=row.next_fire,
    )


def occurrence_of(row: OccurrenceRow) -> Occurrence:
    """One row of the delivery log as a value."""
    return Occurrence(
        item_id=row.item_id,
        user_id=row.user_id,
        kind=ItemKind(row.kind),
        what=row.what,
        outcome=Outcome(row.outcome),
        fire_time=row.fire_time,
        last_fire_time=row.last_fire_time,
        count=row.count,
        recorded_at=row.recorded_at,
        reason=row.reason,
    )
