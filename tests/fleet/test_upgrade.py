"""A database made before the fleet (memory_0003, agenda_0001) upgrades with
``dms db upgrade`` and then serves robots sharing it."""

from __future__ import annotations

from datetime import timedelta

from sqlalchemy import text
from typer.testing import CliRunner

import agenda.migrations as agenda_migrations
from agenda import Agenda, ItemSpec, Outcome
from dms.cli import db_app
from memory import ProfileStore, migrations
from memory.db import make_engine
from tests.fleet.conftest import NOW


def _before_the_fleet(url: str) -> int:
    """Ann's profile with a score and a field, and her reminder, written at the schemas
    of before (no version, no write ids, no claims). Returns the reminder's id."""
    engine = make_engine(url)
    migrations.upgrade_engine(engine, "memory_0003")
    agenda_migrations.upgrade_engine(engine, "agenda_0001")
    engine.dispose()
    engine = make_engine(url)
    with engine.begin() as connection:  # what the code of before wrote
        connection.execute(
            text(
                "INSERT INTO users (user_id, created_at, updated_at, name, interaction_style,"
                " proactivity, proactivity_confidence, attributes, voice_failures,"
                " screen_failures, initiative_taken, initiative_offered)"
                " VALUES ('ann', :t, :t, 'Ann', 'voice', 'unknown', 0, '{}', 0, 0, 0, 0)"
            ),
            {"t": NOW},
        )
        connection.execute(text("INSERT INTO activity_scores VALUES ('ann', 'quiz', 1.0, 1, 2, 0)"))
        item_id = connection.execute(
            text(
                "INSERT INTO agenda_items (user_id, kind, text, schedule, spec, tz, priority,"
                " lead_s, grace_s, created_at, next_fire) VALUES ('ann', 'reminder', 'Pills',"
                " 'at', :spec, 'UTC', 'normal', 0, 600, :t, :fire) RETURNING id"
            ),
            {
                "spec": (NOW + timedelta(minutes=5)).isoformat(),
                "t": NOW.replace(tzinfo=None),
                "fire": (NOW + timedelta(minutes=5)).replace(tzinfo=None),
            },
        ).scalar_one()
    engine.dispose()
    return int(item_id)


def test_dms_db_upgrade_brings_an_old_database_to_the_fleet(fleet_url: str) -> None:
    item_id = _before_the_fleet(fleet_url)
    result = CliRunner().invoke(db_app, ["upgrade", "--db", fleet_url])
    assert result.exit_code == 0, result.output
    assert f"memory_0003 -> {migrations.head()}" in result.output
    robots = [ProfileStore(fleet_url), ProfileStore(fleet_url)]
    agendas = [Agenda.open(fleet_url, claimer=f"robot{index}") for index in range(2)]
    try:
        before = robots[0].get("ann")
        assert (before.name, before.version, before.scores["quiz"].completions) == ("Ann", 0, 2)
        robots[0].record_activity("ann", "quiz", NOW, NOW, "completed", "robot", False)
        after = robots[1].update("ann", NOW, favorite_room="garden", write_id="w1")
        assert after.scores["quiz"].completions == 3 and after.version == 2
        fire = NOW + timedelta(minutes=5)
        got = [agenda.due(fire, "ann") for agenda in agendas]
        assert sorted(len(items) for items in got) == [0, 1]
        (due,) = got[0] or got[1]
        assert due.item_id == item_id
        winner = agendas[0] if got[0] else agendas[1]
        winner.delivered(due, fire)
        assert [o.outcome for o in winner.history("ann")] == [Outcome.DELIVERED]
        added = agendas[0].add(
            ItemSpec(user_id="ann", kind="reminder", text="Call Bea", at=fire), NOW
        )
        assert added.item_id > item_id
    finally:
        for agenda in agendas:
            agenda.close()
        for store in robots:
            store.close()
