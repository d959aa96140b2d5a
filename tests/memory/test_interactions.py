"""Interaction events in the store: appended to a session named by its id or its key,
applied once per write id, refused whole when one is malformed, exported as one table."""

from __future__ import annotations

import csv
import io
import json
from datetime import timedelta
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from memory import ProfileError, ProfileStore
from memory.interactions import COLUMNS, MAX_EVENTS
from memory.sessions_cli import app
from tests.memory.conftest import NOW

SECOND = timedelta(seconds=1)


def _events(*kinds: str, offset: int = 0) -> list[dict[str, Any]]:
    return [
        {"seq": offset + i, "at": NOW + (offset + i) * SECOND, "event": kind}
        for i, kind in enumerate(kinds)
    ]


def test_events_land_in_the_session_the_daemons_key_names(store: ProfileStore) -> None:
    store.get_or_create("ann", NOW)
    session = store.start_session("ann", NOW, write_id="session-abc")
    offered = {
        "seq": 1,
        "at": NOW + 2 * SECOND,
        "event": "offered",
        "offer": 1,
        "offer_kind": "menu",
    }
    tapped = {
        "seq": 2,
        "at": NOW + 9 * SECOND,
        "event": "input",
        "offer": 1,
        "offer_kind": "menu",
        "channel": "screen",
        "value": "quiz",
        "delay_s": 7.0,
    }
    assert store.record_interactions("ann", "session-abc", [*_events("arrived"), offered]) == 2
    assert store.record_interactions("ann", "session-abc", [tapped], write_id="w1") == 1
    assert store.record_interactions("ann", "session-abc", [tapped], write_id="w1") == 1  # replay
    rows = store.interaction_events()
    assert [(r["session"], r["seq"], r["event"]) for r in rows] == [
        (session, 0, "arrived"),
        (session, 1, "offered"),
        (session, 2, "input"),
    ]
    assert rows[2]["t_s"] == 9.0 and rows[2]["delay_s"] == 7.0 and rows[2]["value"] == "quiz"
    assert list(rows[0]) == list(COLUMNS)
    assert store.export("ann")["interactions"][2]["channel"] == "screen"


def test_a_key_that_names_no_session_keeps_the_events_without_one(store: ProfileStore) -> None:
    store.get_or_create("bob", NOW)
    store.record_interactions("bob", "session-never-stored", _events("arrived"))
    (row,) = store.interaction_events()
    assert row["session"] is None and row["user"] == "bob" and row["t_s"] is None


@pytest.mark.parametrize(
    ("bad", "named"),
    [
        ({"event": "danced"}, "event must be one of"),
        ({"channel": "telepathy"}, "channel must be one of"),
        ({"confidence": 1.5}, "confidence must be a number"),
        ({"delay_s": float("nan")}, "delay_s must be a number"),
        ({"value": "x" * 201}, "value must be a string of at most 200"),
        ({"seq": -1}, "seq must be a whole number"),
        ({"understood": "yes"}, "understood must be"),
        ({"colour": "red"}, "unknown field 'colour'"),
    ],
)
def test_a_malformed_event_is_refused_whole_in_one_line(
    store: ProfileStore, bad: dict[str, Any], named: str
) -> None:
    store.get_or_create("ann", NOW)
    good = _events("arrived")[0]
    with pytest.raises(ProfileError, match=named) as refused:
        store.record_interactions("ann", None, [good, {**good, "seq": 1, **bad}])
    assert "\n" not in str(refused.value)
    assert store.interaction_events() == []


def test_too_many_events_in_one_write_are_refused(store: ProfileStore) -> None:
    store.get_or_create("ann", NOW)
    with pytest.raises(ProfileError, match=f"at most {MAX_EVENTS}"):
        store.record_interactions("ann", None, _events(*["input"] * (MAX_EVENTS + 1)))


def test_export_prints_one_row_per_event_as_csv_and_json(tmp_path: Path) -> None:
    db = tmp_path / "dms.db"
    store = ProfileStore(f"sqlite:///{db}")
    for user, start in (("ann", 0), ("bob", 60)):
        store.get_or_create(user, NOW)
        key = f"session-{user}"
        store.start_session(user, NOW + start * SECOND, write_id=key)
        store.record_interactions(user, key, _events("arrived", "left", offset=start))
    store.close()
    runner = CliRunner()
    as_json = runner.invoke(app, ["export", "--events", "--db", str(db)])
    assert as_json.exit_code == 0, as_json.output
    rows = json.loads(as_json.output)
    assert [(r["user"], r["event"], r["t_s"]) for r in rows] == [
        ("ann", "arrived", 0.0),
        ("ann", "left", 1.0),
        ("bob", "arrived", 0.0),
        ("bob", "left", 1.0),
    ]
    as_csv = runner.invoke(app, ["export", "--events", "--format", "csv", "--db", str(db)])
    table = list(csv.DictReader(io.StringIO(as_csv.output)))
    assert list(table[0]) == list(COLUMNS)
    assert [row["event"] for row in table] == [r["event"] for r in rows]
    later = runner.invoke(
        app, ["export", "--events", "--since", (NOW + 30 * SECOND).isoformat(), "--db", str(db)]
    )
    assert {r["user"] for r in json.loads(later.output)} == {"bob"}
