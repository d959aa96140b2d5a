"""The agenda across a kill -9 while its database write waits: never delivered twice.

A reminder is delivered while another process holds SQLite's write lock, so the
delivery's database write cannot land; the daemon is killed (-9), the lock released and
the daemon started again with the user present, within the reminder's grace time. The
journal (``dms.db.mini.agenda-spool``) held the delivery, the restart replays it before it
computes what is due, and the reminder is not spoken again.
"""

from __future__ import annotations

import sqlite3
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import pytest

from tests.integration.harness import Collector, DaemonProcess, client_session, put, query
from tests.integration.test_storage import LockHolder

pytestmark = pytest.mark.integration

ANN_READY = {"present": True, "user_id": "ann", "ready": True}
CONFIG = "[privacy]\nserve_profiles = true\n"


def _ts(message: dict[str, Any]) -> float:
    return datetime.fromisoformat(message["time"].replace("Z", "+00:00")).timestamp()


def _is_reminder(decision: dict[str, Any]) -> bool:
    return bool(
        decision["action"] == "start"
        and decision["activity"] == "notification"
        and decision["reason"] == "agenda"
    )


def test_a_reminder_delivered_before_a_kill_9_is_not_delivered_again(tmp_path: Path) -> None:
    daemon = DaemonProcess(tmp_path, extra_config=CONFIG)
    file = tmp_path / "dms.db"
    session = client_session(daemon.port)
    holder: LockHolder | None = None
    try:
        daemon.start(session)
        decisions = Collector(session, "robots/mini/dms/decision")
        states = Collector(session, "robots/mini/dms/state")
        put(session, "perception/user", ANN_READY)
        put(session, "request", {"action": "start", "activity": "quiz", "by": "ann"})
        # the request may be served in the tick before Ann's session begins: the agenda
        # takes items for users the robot has met, so wait until it has met her
        state = states.wait_for(
            lambda s: (
                (s["activity"] or {}).get("name") == "quiz" and (s["user"] or {}).get("id") == "ann"
            )
        )
        fire = _ts(state) + 4  # it pauses the quiz to speak
        replies = query(
            session,
            "agenda/ann",
            {
                "op": "add",
                "kind": "reminder",
                "text": "Time for your pills",
                "at": datetime.fromtimestamp(fire, UTC).isoformat(),
                "grace_s": 600,
            },
        )
        assert replies and replies[0][0], replies
        item_id = replies[0][1]["item"]["id"]
        holder = LockHolder(file)  # the delivery's database write cannot land now
        decisions.wait_for(_is_reminder, timeout=15)
        states.wait_for(lambda s: _ts(s) > fire + 1.5)  # the write was tried and failed
        daemon.kill()  # kill -9
        journal = Path(f"{file}.mini.agenda-spool").read_text()
        assert '"outcome": "delivered"' in journal
        holder.release()
        holder = None
    finally:
        if holder is not None:
            holder.release()
        daemon.kill()
        session.close()

    again = DaemonProcess(tmp_path, extra_config=CONFIG)
    session = client_session(again.port)
    try:
        again.start(session)
        decisions = Collector(session, "robots/mini/dms/decision")
        states = Collector(session, "robots/mini/dms/state")
        put(session, "perception/user", ANN_READY)
        states.wait_for(lambda s: (s["user"] or {}).get("id") == "ann")
        mark = states.mark()
        states.wait_count(mark + 8, timeout=15)  # 4 s of ticks with ann present, in grace
        assert not [d for d in decisions.messages if _is_reminder(d)], decisions.messages
        assert again.terminate() == 0
    finally:
        again.kill()
        session.close()

    with sqlite3.connect(file) as connection:
        rows = connection.execute(
            "SELECT outcome, count FROM agenda_occurrences WHERE item_id = ?", (item_id,)
        ).fetchall()
        (next_fire,) = connection.execute(
            "SELECT next_fire FROM agenda_items WHERE id = ?", (item_id,)
        ).fetchone()
    assert rows == [("delivered", 1)]
    assert next_fire is None
    assert not Path(f"{file}.mini.agenda-spool").exists()
