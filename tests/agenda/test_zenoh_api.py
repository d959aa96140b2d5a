"""The pure logic behind the ``agenda/<user_id>`` queryable: replies and error replies."""

from __future__ import annotations

import json
from datetime import timedelta

from agenda import Agenda
from agenda.zenoh_api import handle_query
from tests.agenda.conftest import START


def _query(agenda: Agenda, user: str, payload: object | bytes | None) -> tuple[bool, dict]:  # type: ignore[type-arg]
    raw = payload if payload is None or isinstance(payload, bytes) else json.dumps(payload).encode()
    return handle_query(agenda, user, raw, START)


def test_no_payload_lists_the_users_upcoming_items(agenda: Agenda) -> None:
    assert _query(agenda, "ann", None) == (True, {"items": []})
    ok, added = _query(
        agenda, "ann", {"op": "add", "kind": "reminder", "text": "Pills", "every": 3600}
    )
    assert ok and added["item"]["user_id"] == "ann"
    _query(agenda, "bob", {"op": "add", "kind": "event", "activity": "talk", "every": 7200})
    ok, body = _query(agenda, "ann", None)
    assert ok
    (item,) = body["items"]
    assert item["id"] == added["item"]["id"]
    assert item["next_fire"] == "2026-11-23T10:00:00.000Z"
    assert item["kind"] == "reminder" and item["text"] == "Pills" and item["waiting"] is False
    ok, everyone = _query(agenda, "*", {"op": "list", "limit": 5})
    assert ok and [i["user_id"] for i in everyone["items"]] == ["ann", "bob"]


def test_add_takes_itemspec_fields_and_ignores_unknown_ones(agenda: Agenda) -> None:
    ok, body = _query(
        agenda,
        "ann",
        {
            "op": "add",
            "kind": "event",
            "activity": "cognitive_stimulation",
            "cron": "0 10 * * MON",
            "tz": "Europe/Madrid",
            "priority": "high",
            "lead_s": 300,
            "grace_s": 900,
            "colour": "blue",
        },
    )
    assert ok, body
    item = body["item"]
    assert (item["priority"], item["lead_s"], item["grace_s"]) == ("high", 300, 900)
    # START is 10:00 on a Monday in Madrid: the first occurrence is now (inclusive).
    assert item["next_fire"] == "2026-11-23T09:00:00.000Z"


def test_remove_by_id_only_for_the_owner(agenda: Agenda) -> None:
    _, added = _query(agenda, "ann", {"op": "add", "kind": "reminder", "text": "x", "every": 60})
    item_id = added["item"]["id"]
    ok, body = _query(agenda, "bob", {"op": "remove", "id": item_id})
    assert not ok and "not bob's" in body["error"]
    assert _query(agenda, "ann", {"op": "remove", "id": item_id}) == (True, {"removed": item_id})
    ok, body = _query(agenda, "ann", {"op": "remove", "id": item_id})
    assert (ok, body) == (False, {"error": f"no agenda item {item_id}"})


def test_bad_queries_get_an_error_reply_and_change_nothing(agenda: Agenda) -> None:
    bad: list[object | bytes] = [
        b"{not json",
        b"\xff\xfe",
        [1, 2],
        {"op": "dance"},
        {"op": "list", "limit": 0},
        {"op": "list", "limit": True},
        {"op": "remove"},
        {"op": "remove", "id": "7"},
        {"op": "add", "kind": "reminder", "text": "x"},
        {"op": "add", "kind": "reminder", "text": "x", "cron": "every day"},
        {"op": "add", "kind": "reminder", "text": "x", "every": 60, "tz": "Nowhere/City"},
        {"op": "add", "kind": "event", "activity": "juggling", "every": 60},
        {"op": "add", "kind": "party", "every": 60},
        {"op": "add", "kind": "reminder", "text": "x", "every": 60, "user_id": "bob"},
        {"op": "add", "kind": "reminder", "text": "x", "at": "tomorrow"},
    ]
    for payload in bad:
        ok, body = _query(agenda, "ann", payload)
        assert not ok, payload
        assert set(body) == {"error"} and body["error"] and "\n" not in body["error"]
    ok, body = _query(agenda, "*", {"op": "add", "kind": "reminder", "text": "x", "every": 60})
    assert not ok and "one user" in body["error"]
    assert agenda.upcoming(None, START + timedelta(days=1)) == []
