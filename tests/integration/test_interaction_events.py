"""A real session's interaction events, written by a real daemon and exported as one table.

Ann arrives and asks for the menu; she taps the quiz, touches the robot's right shoulder
during it and answers "continue or stop?" by voice, once misheard, then "stop"; she
leaves. ``dms sessions export --events`` prints her session as the events a participant
model learns from, with the times the daemon published its decisions at.
"""

from __future__ import annotations

import csv
import io
import json
import subprocess
import sys
from datetime import datetime
from pathlib import Path
from typing import Any

import pytest

from memory.interactions import COLUMNS
from tests.integration.harness import Collector, put, running_daemon

pytestmark = pytest.mark.integration


def _export(db: str, fmt: str) -> str:
    command = ["sessions", "export", "--events", "--format", fmt, "--db", db]
    done = subprocess.run(
        [sys.executable, "-m", "dms.cli", *command], capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 0, done.stderr
    return done.stdout


def _at(text: str) -> datetime:
    return datetime.fromisoformat(text)


def _same(stored: str, published: str) -> bool:
    """The same tick: ``dms/decision`` names its time to the millisecond."""
    return abs((_at(stored) - _at(published)).total_seconds()) < 0.001


def test_a_real_session_is_stored_with_its_offers_inputs_and_timings(tmp_path: Path) -> None:
    with running_daemon(tmp_path) as (daemon, session):
        decisions = Collector(session, "robots/mini/dms/decision")
        states = Collector(session, "robots/mini/dms/state")
        commands = Collector(session, "robots/mini/robot/command")
        states.wait_count(1)
        mark = decisions.mark()
        put(session, "perception/user", {"present": True, "user_id": "ann", "ready": True})
        # Her session's first choice: the menu (her initiative), or the robot's pick.
        menu = decisions.wait_for(
            lambda d: d["action"] == "start" and d["chosen_by"] in ("user", "robot"), start=mark
        )
        if menu["activity"] != "menu":
            mark = decisions.mark()
            put(session, "request", {"action": "start", "activity": "menu", "by": "ann"})
            menu = decisions.wait_for(
                lambda d: d["action"] == "start" and d["activity"] == "menu", start=mark
            )
        commands.wait_for(lambda c: c["channel"] == "screen" and bool(c["args"].get("choices")))
        mark = decisions.mark()
        put(session, "perception/screen", {"choice": "quiz"})
        quiz = decisions.wait_for(
            lambda d: d["action"] == "start" and d["activity"] == "quiz", start=mark
        )
        mark = decisions.mark()
        put(session, "perception/touch", {"part": "right_shoulder", "kind": "tap"})
        asked = decisions.wait_for(
            lambda d: d["action"] == "ask" and d["reason"] == "confirm_cancel", start=mark
        )
        mark = decisions.mark()
        put(session, "perception/speech", {"text": "stop", "confidence": 0.2})
        put(session, "perception/speech", {"text": "stop", "confidence": 0.9})
        stopped = decisions.wait_for(
            lambda d: d["action"] == "cancel" and d["activity"] == "quiz", start=mark
        )
        put(session, "perception/user", {"present": False, "user_id": None, "ready": False})
        states.wait_for(lambda s: s["user"] is None, start=states.mark())
        assert daemon.terminate() == 0

    rows: list[dict[str, Any]] = json.loads(_export(daemon.db, "json"))
    ann = [row for row in rows if row["user"] == "ann"]
    assert ann and {row["session"] for row in ann} == {ann[0]["session"]} != {None}
    assert [row["seq"] for row in ann] == list(range(len(ann)))
    assert ann[0]["event"] == "arrived" and ann[-1]["event"] == "left"

    def one(**wanted: Any) -> dict[str, Any]:
        found = [r for r in ann if all(r[k] == v for k, v in wanted.items())]
        assert len(found) == 1, (wanted, found)
        return found[0]

    offered = one(event="offered", offer_kind="menu")
    assert _same(offered["time"], menu["time"])  # the decision's tick
    tap = one(event="input", channel="screen")
    assert (tap["value"], tap["offer"], tap["offer_kind"]) == ("quiz", offered["offer"], "menu")
    waited = (_at(tap["time"]) - _at(offered["time"])).total_seconds()
    assert tap["delay_s"] == pytest.approx(waited, abs=1e-3)
    assert 0 <= tap["delay_s"] <= (_at(quiz["time"]) - _at(menu["time"])).total_seconds()
    assert one(event="started", activity="quiz")["by"] == "user"
    touch = one(event="input", channel="touch")
    assert touch["value"] == "right_shoulder" and touch["offer"] is None
    confirm = one(event="offered", offer_kind="confirm")
    assert confirm["activity"] == "quiz" and _same(confirm["time"], asked["time"])
    spoken = [r for r in ann if r["event"] == "input" and r["channel"] == "voice"]
    assert [(r["confidence"], r["understood"], r["offer"]) for r in spoken] == [
        (0.2, False, confirm["offer"]),
        (0.9, True, confirm["offer"]),
    ]
    assert spoken[0]["delay_s"] <= spoken[1]["delay_s"]
    cancelled = one(event="cancelled", activity="quiz")
    assert (cancelled["by"], cancelled["detail"]) == ("user", "confirm_cancel")
    assert _same(cancelled["time"], stopped["time"])
    assert not [r for r in ann if r["event"] == "unanswered"]  # every offer was answered

    table = list(csv.DictReader(io.StringIO(_export(daemon.db, "csv"))))
    assert list(table[0]) == list(COLUMNS)
    assert len(table) == len(rows)
    for row, parsed in zip(table, rows, strict=True):
        assert row == {k: "" if v is None else str(v) for k, v in parsed.items()}
