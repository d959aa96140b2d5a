"""Schedules: from a stored spec to fire times, on APScheduler 3.x triggers.

The triggers are used only as calculators: ``get_next_fire_time(previous, now)``
against the ``now`` the daemon passes in. No scheduler, no thread, no system clock,
so an agenda behaves the same on the virtual clock as on the real one.

Times inside the agenda's index are integer microseconds since the Unix epoch
(:func:`to_us`), exact and cheap to compare on every tick.

Two traps of crontab on APScheduler 3.x are handled here:

- numeric weekdays: crontab counts 0 (and 7) as Sunday, APScheduler 3.x as Monday;
  numeric day-of-week fields are translated to day names with crontab's meaning.
- the hour repeated when daylight saving time ends: a job at a fixed hour
  (``30 2 * * *``) runs once, as Vixie cron does; a job whose hour field is ``*``
  runs in both copies of the hour, as elapsed time demands.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from datetime import UTC, datetime, timedelta, tzinfo
from enum import StrEnum
from typing import Protocol
from zoneinfo import ZoneInfo, ZoneInfoNotFoundError

from apscheduler.triggers.cron import CronTrigger
from apscheduler.triggers.date import DateTrigger
from apscheduler.triggers.interval import IntervalTrigger

from agenda.errors import AgendaError

EPOCH = datetime(1970, 1, 1, tzinfo=UTC)
_US = timedelta(microseconds=1)
NEVER_US = 2**62
"""A time after every real one (about the year 148,000)."""

MAX_EVERY_S = 366 * 86400
_MEMO_SIZE = 256
_WEEKDAY_NAMES = ("sun", "mon", "tue", "wed", "thu", "fri", "sat")
_DOW_NUMBERED = re.compile(r"\d")


class ScheduleKind(StrEnum):
    """How an item repeats."""

    AT = "at"
    """Once, at a date and time."""
    CRON = "cron"
    """On a 5-field crontab expression, in the item's time zone."""
    EVERY = "every"
    """Every N seconds of elapsed time from an anchor."""


def to_us(when: datetime) -> int:
    """Microseconds since the epoch, exactly (no float rounding)."""
    return (when - EPOCH) // _US


def from_us(us: int) -> datetime:
    """The UTC datetime of :func:`to_us`."""
    return EPOCH + timedelta(microseconds=us)


def zone(name: str) -> tzinfo:
    """The IANA time zone ``name``; AgendaError if there is no such zone."""
    if name == "UTC":
        return UTC
    try:
        return ZoneInfo(name)
    except (ZoneInfoNotFoundError, ValueError, OSError):
        raise AgendaError(
            f"unknown time zone {name!r} (use an IANA name like Europe/Madrid)"
        ) from None


def localize(at: datetime, tz: tzinfo) -> datetime:
    """``at`` as an aware UTC datetime; naive means wall time in ``tz``.

    A wall time that does not exist in ``tz`` (skipped when clocks go forward) is
    refused; an ambiguous one (repeated when clocks go back) is its first instance.
    """
    if at.tzinfo is not None:
        return at.astimezone(UTC)
    aware = at.replace(tzinfo=tz, fold=0)
    back = aware.astimezone(UTC).astimezone(tz).replace(tzinfo=None)
    if back != at.replace(fold=0):
        raise AgendaError(f"{at.isoformat()} does not exist in {tz} (clocks go forward then)")
    return aware.astimezone(UTC)


def crontab_to_apscheduler(expression: str) -> tuple[str, ...]:
    """The five fields of ``expression`` with crontab's weekday numbers as names.

    Raises AgendaError when it does not have five fields or a weekday is out of range.
    """
    fields = expression.split()
    if len(fields) != 5:
        raise AgendaError(
            f"invalid cron expression {expression!r}: expected 5 fields "
            f"(minute hour day month weekday), got {len(fields)}"
        )
    dow = fields[4]
    if _DOW_NUMBERED.search(dow):
        fields[4] = ",".join(_WEEKDAY_NAMES[d] for d in sorted(_crontab_weekdays(dow, expression)))
    return tuple(fields)


def _crontab_weekdays(field: str, expression: str) -> set[int]:
    """The weekdays (0 = Sunday) a crontab day-of-week field selects."""
    names = {name: index for index, name in enumerate(_WEEKDAY_NAMES)}

    def number(token: str) -> int:
        token = token.strip().lower()
        if token in names:
            return names[token]
        if not token.isdigit() or int(token) > 7:
            raise AgendaError(f"invalid cron expression {expression!r}: bad weekday {token!r}")
        return int(token) % 7

    days: set[int] = set()
    for part in field.split(","):
        span, _, step_text = part.partition("/")
        step = 1
        if step_text:
            if not step_text.isdigit() or int(step_text) == 0:
                raise AgendaError(f"invalid cron expression {expression!r}: bad step {part!r}")
            step = int(step_text)
        if span in ("*", "?"):
            low, high = 0, 6
        elif "-" in span:
            first, _, last = span.partition("-")
            low, high = number(first), number(last)
            if last.strip() == "7":
                high = 7
            if low > high:
                raise AgendaError(f"invalid cron expression {expression!r}: bad range {part!r}")
        else:
            low = number(span)
            high = 6 if step_text else low
        days.update(d % 7 for d in range(low, high + 1, step))
    return days


class Trigger(Protocol):
    """What the agenda asks of an APScheduler trigger."""

    def get_next_fire_time(
        self, previous_fire_time: datetime | None, now: datetime
    ) -> datetime | None: ...


@dataclass(frozen=True, slots=True)
class Schedule:
    """A stored schedule made executable: its trigger and the rules around it."""

    kind: ScheduleKind
    trigger: Trigger
    skip_repeated_hour: bool
    """A fixed-hour cron job: skip the second instance of a repeated wall time."""
    _after: dict[int, int | None] = field(default_factory=dict, compare=False, repr=False)
    """Memo of :meth:`after_us`: items sharing a schedule (a weekly class for everyone)
    fall due together, and a cron step costs ~100 µs."""

    def first_at_or_after(self, now: datetime) -> datetime | None:
        """The first fire time at or after ``now`` (for a one-off item: its date)."""
        fire = self.trigger.get_next_fire_time(None, now)
        return self._skip_repeat(fire)

    def after(self, fire: datetime) -> datetime | None:
        """The fire time that follows ``fire``; None when there is no more."""
        return self._skip_repeat(self.trigger.get_next_fire_time(fire, fire))

    def _skip_repeat(self, fire: datetime | None) -> datetime | None:
        while fire is not None and self.skip_repeated_hour and _second_instance(fire):
            fire = self.trigger.get_next_fire_time(fire, fire)
        return fire

    def first_us(self, now_us: int) -> int | None:
        fire = self.first_at_or_after(from_us(now_us))
        return None if fire is None else to_us(fire)

    def after_us(self, fire_us: int) -> int | None:
        memo = self._after
        if fire_us in memo:
            return memo[fire_us]
        fire = self.after(from_us(fire_us))
        result = None if fire is None else to_us(fire)
        if len(memo) >= _MEMO_SIZE:
            memo.clear()
        memo[fire_us] = result
        return result


def _second_instance(fire: datetime) -> bool:
    """Whether ``fire`` is the later copy of a wall time repeated when clocks go back."""
    if fire.fold != 1:
        return False
    return fire.replace(fold=0).utcoffset() != fire.utcoffset()


def build(kind: ScheduleKind, spec: str, tz_name: str, anchor: datetime | None) -> Schedule:
    """The executable schedule of a stored one.

    ``spec`` is an ISO UTC instant (``at``), a crontab expression (``cron``) or a
    number of seconds (``every``, counted from ``anchor``).
    """
    tz = zone(tz_name)
    if kind is ScheduleKind.AT:
        try:
            run_date = datetime.fromisoformat(spec)
        except ValueError:
            raise AgendaError(f"invalid date {spec!r}") from None
        return Schedule(kind, DateTrigger(run_date=localize(run_date, UTC), timezone=UTC), False)
    if kind is ScheduleKind.CRON:
        fields = crontab_to_apscheduler(spec)
        try:
            trigger = CronTrigger(
                minute=fields[0],
                hour=fields[1],
                day=fields[2],
                month=fields[3],
                day_of_week=fields[4],
                timezone=tz,
            )
        except ValueError as error:
            raise AgendaError(f"invalid cron expression {spec!r}: {error}") from None
        return Schedule(kind, trigger, skip_repeated_hour=fields[1] != "*")
    try:
        seconds = int(spec)
    except ValueError:
        raise AgendaError(f"invalid interval {spec!r}") from None
    if anchor is None:
        raise AgendaError("an interval needs an anchor time")
    # Elapsed time, not wall time: the interval runs in UTC whatever the item's zone.
    return Schedule(
        kind,
        IntervalTrigger(seconds=seconds, start_date=anchor.astimezone(UTC), timezone=UTC),
        False,
    )
