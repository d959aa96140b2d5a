"""Fire times: cron across daylight saving changes, crontab weekdays, wall times."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

import pytest

from agenda import Agenda, AgendaError, ItemSpec
from agenda.schedule import ScheduleKind, build, crontab_to_apscheduler, localize, zone

MADRID = "Europe/Madrid"


def _fires(expression: str, tz: str, start: datetime, count: int) -> list[datetime]:
    schedule = build(ScheduleKind.CRON, expression, tz, None)
    fire = schedule.first_at_or_after(start)
    out: list[datetime] = []
    while fire is not None and len(out) < count:
        out.append(fire.astimezone(UTC))
        fire = schedule.after(fire)
    return out


def test_weekly_cron_keeps_local_time_across_the_october_change() -> None:
    fires = _fires("0 10 * * MON", MADRID, datetime(2026, 10, 12, tzinfo=UTC), 3)
    # Summer time (UTC+2) until Sunday 25 October, then UTC+1: 10:00 in Madrid both times.
    assert fires == [
        datetime(2026, 10, 12, 8, 0, tzinfo=UTC),
        datetime(2026, 10, 19, 8, 0, tzinfo=UTC),
        datetime(2026, 10, 26, 9, 0, tzinfo=UTC),
    ]


def test_fixed_hour_job_runs_once_in_the_repeated_hour() -> None:
    fires = _fires("30 2 * * *", MADRID, datetime(2026, 10, 24, 12, 0, tzinfo=UTC), 2)
    # 02:30 happens twice on 25 October (CEST, then CET); the reminder is said once.
    assert fires == [
        datetime(2026, 10, 25, 0, 30, tzinfo=UTC),
        datetime(2026, 10, 26, 1, 30, tzinfo=UTC),
    ]


def test_hourly_job_runs_every_elapsed_hour_through_the_change() -> None:
    fires = _fires("0 * * * *", MADRID, datetime(2026, 10, 24, 23, 30, tzinfo=UTC), 4)
    assert [f - fires[0] for f in fires] == [timedelta(hours=h) for h in range(4)]


def test_crontab_weekday_numbers_mean_what_crontab_says() -> None:
    assert crontab_to_apscheduler("0 10 * * 1")[4] == "mon"
    assert crontab_to_apscheduler("0 10 * * 0")[4] == "sun"
    assert crontab_to_apscheduler("0 10 * * 7")[4] == "sun"
    assert crontab_to_apscheduler("0 10 * * 1-5")[4] == "mon,tue,wed,thu,fri"
    assert crontab_to_apscheduler("0 10 * * */3")[4] == "sun,wed,sat"
    assert crontab_to_apscheduler("0 10 * * MON")[4] == "MON"
    monday = _fires("0 10 * * 1", "UTC", datetime(2026, 11, 24, tzinfo=UTC), 1)[0]
    assert monday.weekday() == 0
    with pytest.raises(AgendaError, match="weekday"):
        crontab_to_apscheduler("0 10 * * 8")


def test_naive_wall_time_is_read_in_the_zone_and_gaps_are_refused() -> None:
    tz = zone(MADRID)
    assert localize(datetime(2026, 11, 23, 16, 45), tz) == datetime(
        2026, 11, 23, 15, 45, tzinfo=UTC
    )
    # 02:30 on 29 March 2026 does not exist in Madrid: clocks jump from 02:00 to 03:00.
    with pytest.raises(AgendaError, match="does not exist"):
        localize(datetime(2026, 3, 29, 2, 30), tz)


def test_agenda_delivers_a_cron_event_across_the_change_on_virtual_time(agenda: Agenda) -> None:
    start = datetime(2026, 10, 19, 9, 0, tzinfo=UTC)  # Monday 11:00 in Madrid, after the event
    agenda.add(
        ItemSpec(
            user_id="ann",
            kind="event",
            activity="cognitive_stimulation",
            cron="0 10 * * MON",
            tz=MADRID,
        ),
        start,
    )
    # The next Monday is after the change: 10:00 CET is 09:00 UTC, not 08:00.
    assert agenda.due(datetime(2026, 10, 26, 8, 0, tzinfo=UTC), "ann") == []
    (item,) = agenda.due(datetime(2026, 10, 26, 9, 0, tzinfo=UTC), "ann")
    assert item.fire_time == datetime(2026, 10, 26, 9, 0, tzinfo=UTC)
