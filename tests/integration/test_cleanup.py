"""A cancelled activity's cleanup from outside: a real ``dms run`` and a real Zenoh session.

A caregiver's app stops a quiz mid-question by asking for bingo: the daemon decides
cancel and start in one tick, and the robot is told to say that the quiz stops, with
the score, before bingo's first sentence.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.integration.harness import Collector, put, running_daemon

pytestmark = pytest.mark.integration

ANN_READY = {"present": True, "user_id": "ann", "ready": True, "engagement": 0.8}


def _speech(command: dict[str, object]) -> str:
    args = command.get("args")
    return (
        str(args.get("text", ""))
        if command.get("channel") == "speech" and isinstance(args, dict)
        else ""
    )


def test_a_quiz_cancelled_mid_question_says_it_stops(tmp_path: Path) -> None:
    with running_daemon(tmp_path) as (_daemon, session):
        decisions = Collector(session, "robots/mini/dms/decision")
        states = Collector(session, "robots/mini/dms/state")
        commands = Collector(session, "robots/mini/robot/command")
        put(session, "perception/user", ANN_READY)
        put(session, "request", {"action": "start", "activity": "quiz", "by": "caregiver"})
        decisions.wait_for(lambda d: d["action"] == "start" and d["activity"] == "quiz")
        states.wait_for(lambda s: "ASK" in ((s["activity"] or {}).get("state") or ""), timeout=60)
        mark = decisions.mark()
        said = commands.mark()
        put(session, "request", {"action": "start", "activity": "bingo", "by": "caregiver"})
        cancel = decisions.wait_for(lambda d: d["action"] == "cancel", start=mark)
        start = decisions.wait_for(lambda d: d["action"] == "start", start=mark)
        assert cancel["activity"] == "quiz" and start["activity"] == "bingo"
        assert cancel["time"] == start["time"], "cancel and the next start in one tick"
        stop = commands.wait_for(lambda c: "stop the quiz here" in _speech(c), start=said)
        assert "right out of" in _speech(stop)
        bingo = commands.wait_for(lambda c: _speech(c).startswith("Let's play bingo"), start=said)
        texts = [_speech(c) for c in commands.messages[said:]]
        assert texts.index(_speech(stop)) < texts.index(_speech(bingo))
