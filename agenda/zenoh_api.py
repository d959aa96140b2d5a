"""What the agenda answers on the queryable ``robots/<id>/agenda/<user_id>``.

Pure logic; the daemon's bus owns Zenoh and calls :func:`handle_query` under its
lock with the daemon's ``now``. The reply is ``(ok, body)``: the bus sends ``body``
as a reply when ``ok`` and as an error reply otherwise, never silence.

Payloads (JSON objects; unknown fields are ignored, as everywhere in docs/contract.md):

- none, or ``{"op": "list", "limit": 20}``: ``{"items": [upcoming item, ...]}``
- ``{"op": "add", "kind": ..., ...ItemSpec fields}``: ``{"item": {...}}``
- ``{"op": "remove", "id": 7}``: ``{"removed": 7}``

``<user_id>`` ``*`` lists every user's items; add and remove need one user.
"""

from __future__ import annotations

import json
from datetime import datetime
from typing import Any

from agenda.errors import AgendaError
from agenda.items import ItemSpec
from agenda.service import Agenda
from dms.kernel.keys import ALL_USERS

DEFAULT_LIMIT = 20
MAX_LIMIT = 1000


def handle_query(
    agenda: Agenda, user_id: str, payload: bytes | None, now: datetime
) -> tuple[bool, dict[str, Any]]:
    """Answer one query on ``agenda/<user_id>``; ``(False, {"error": ...})`` on bad input."""
    try:
        return True, _answer(agenda, user_id, _parse(payload), now)
    except AgendaError as error:
        return False, {"error": str(error)}


def _parse(payload: bytes | None) -> dict[str, Any]:
    if payload is None or not payload.strip():
        return {"op": "list"}
    try:
        data = json.loads(payload.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as error:
        raise AgendaError(f"payload is not UTF-8 JSON: {error}") from None
    if not isinstance(data, dict):
        raise AgendaError("payload must be a JSON object")
    return data


def _answer(agenda: Agenda, user_id: str, data: dict[str, Any], now: datetime) -> dict[str, Any]:
    op = data.get("op", "list")
    everyone = user_id in ALL_USERS
    if op == "list":
        limit = data.get("limit", DEFAULT_LIMIT)
        if isinstance(limit, bool) or not isinstance(limit, int) or not 1 <= limit <= MAX_LIMIT:
            raise AgendaError(f"limit must be an integer from 1 to {MAX_LIMIT}")
        items = agenda.upcoming(None if everyone else user_id, now, limit)
        return {"items": [item.to_json() for item in items]}
    if everyone:
        raise AgendaError(f"{op!r} needs one user in the key, not {user_id!r}")
    if op == "add":
        fields = {k: v for k, v in data.items() if k in ItemSpec.model_fields}
        given = fields.setdefault("user_id", user_id)
        if given != user_id:
            raise AgendaError(f"user_id {given!r} does not match the key's user {user_id!r}")
        return {"item": agenda.add(ItemSpec.from_data(fields), now).to_json()}
    if op == "remove":
        item_id = data.get("id")
        if isinstance(item_id, bool) or not isinstance(item_id, int):
            raise AgendaError("remove needs an integer id")
        if agenda.get(item_id).user_id != user_id:
            raise AgendaError(f"agenda item {item_id} is not {user_id}'s")
        agenda.remove(item_id)
        return {"removed": item_id}
    raise AgendaError(f"unknown op {op!r} (list, add or remove)")
