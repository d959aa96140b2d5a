"""The daemon as other processes see it: a real ``dms run`` and a real Zenoh session.

The test's session acts as perception and as a caregiver's app, on 127.0.0.1 only.
"""

from __future__ import annotations

import itertools
import re
import signal
import threading
from datetime import datetime
from pathlib import Path
from typing import Any

import pytest
import zenoh

from tests.integration.harness import (
    Collector,
    DaemonProcess,
    client_session,
    put,
    query,
    running_daemon,
    token_deleted,
)

pytestmark = pytest.mark.integration

ANN_READY = {"present": True, "user_id": "ann", "ready": True, "engagement": 0.8}


def _ts(message: dict[str, Any]) -> float:
    return datetime.fromisoformat(message["time"].replace("Z", "+00:00")).timestamp()


def test_state_at_2hz_and_contract_shape(tmp_path: Path) -> None:
    with running_daemon(tmp_path) as (_daemon, session):
        states = Collector(session, "robots/mini/dms/state")
        got = states.wait_count(7, timeout=10)[-6:]
        ticks = [m["tick"] for m in got]
        assert ticks == sorted(ticks)
        spans = [_ts(b) - _ts(a) for a, b in itertools.pairwise(got)]
        assert all(0.3 <= s <= 0.7 for s in spans), spans
        state = got[-1]
        assert state["robot"] == "mini" and state["mode"] == "motivation"
        assert set(state["motivation"]) == {"dominant", "drives", "motivations", "wellbeing"}
        assert state["activity"]["manager"] == "relax"
        # a healthy default run: parameters nobody sends are no fault
        assert state["inputs"]["params/robot"] == state["inputs"]["params/env"] == "not_published"
        replies = query(session, "dms/state")
        assert replies and replies[0][0] and replies[0][1]["robot"] == "mini"


def test_request_starts_an_activity_and_cancel_stops_it(tmp_path: Path) -> None:
    with running_daemon(tmp_path) as (_daemon, session):
        decisions = Collector(session, "robots/mini/dms/decision")
        states = Collector(session, "robots/mini/dms/state")
        states.wait_count(1)
        put(session, "request", {"action": "start", "activity": "jokes", "by": "caregiver"})
        started = decisions.wait_for(lambda d: d["action"] == "start" and d["activity"] == "jokes")
        assert started["reason"] == "user_request" and started["manager"] == "entertainment"
        states.wait_for(lambda s: (s["activity"] or {}).get("name") == "jokes")
        mark = decisions.mark()
        put(session, "request", {"action": "cancel", "activity": "jokes", "by": "caregiver"})
        cancelled = decisions.wait_for(lambda d: d["action"] == "cancel", start=mark)
        assert cancelled["activity"] == "jokes" and cancelled["reason"] == "user_request"


def test_shoulder_touch_asks_then_stop_cancels_and_continue_resumes(tmp_path: Path) -> None:
    with running_daemon(tmp_path) as (_daemon, session):
        decisions = Collector(session, "robots/mini/dms/decision")
        commands = Collector(session, "robots/mini/robot/command")
        put(session, "perception/user", ANN_READY)
        put(session, "request", {"action": "start", "activity": "quiz", "by": "ann"})
        decisions.wait_for(lambda d: d["action"] == "start" and d["activity"] == "quiz")
        # continue: the quiz resumes
        mark = decisions.mark()
        put(session, "perception/touch", {"part": "right_shoulder", "kind": "tap"})
        decisions.wait_for(
            lambda d: d["action"] == "pause" and d["reason"] == "confirm_cancel", start=mark
        )
        decisions.wait_for(
            lambda d: d["action"] == "ask" and d["reason"] == "confirm_cancel", start=mark
        )
        commands.wait_for(lambda c: c["channel"] == "speech" and "stop" in str(c["args"]).lower())
        put(session, "perception/speech", {"text": "continue", "confidence": 0.9})
        resumed = decisions.wait_for(lambda d: d["action"] == "resume", start=mark)
        assert resumed["activity"] == "quiz" and resumed["reason"] == "confirm_cancel"
        # stop: the quiz is cancelled
        mark = decisions.mark()
        put(session, "perception/touch", {"part": "right_shoulder", "kind": "tap"})
        decisions.wait_for(lambda d: d["action"] == "ask", start=mark)
        put(session, "perception/screen", {"choice": "stop"})
        cancelled = decisions.wait_for(lambda d: d["action"] == "cancel", start=mark)
        assert cancelled["activity"] == "quiz" and cancelled["reason"] == "confirm_cancel"


SERVE_PROFILES = "[privacy]\nserve_profiles = true\n"


def test_a_reminder_pauses_the_activity_speaks_and_resumes_it(tmp_path: Path) -> None:
    with running_daemon(tmp_path, SERVE_PROFILES) as (_daemon, session):
        decisions = Collector(session, "robots/mini/dms/decision")
        states = Collector(session, "robots/mini/dms/state")
        put(session, "perception/user", ANN_READY)
        put(session, "request", {"action": "start", "activity": "quiz", "by": "ann"})
        decisions.wait_for(lambda d: d["action"] == "start" and d["activity"] == "quiz")
        # the request may be served in the tick before Ann's session begins: the agenda
        # takes items for users the robot has met, so wait until it has met her
        state = states.wait_for(
            lambda s: (
                (s["activity"] or {}).get("name") == "quiz" and (s["user"] or {}).get("id") == "ann"
            )
        )
        at = datetime.fromtimestamp(_ts(state) + 2).isoformat()
        replies = query(
            session,
            "agenda/ann",
            {
                "op": "add",
                "user_id": "ann",
                "kind": "reminder",
                "text": "Time for your pills",
                "at": at,
                "tz": "UTC",
            },
        )
        assert replies and replies[0][0], replies
        paused = decisions.wait_for(
            lambda d: d["action"] == "pause" and d["reason"] == "agenda", timeout=15
        )
        assert paused["activity"] == "quiz"
        decisions.wait_for(lambda d: d["action"] == "start" and d["activity"] == "notification")
        states.wait_for(lambda s: (s["suspended"] or {}).get("name") == "quiz")
        resumed = decisions.wait_for(
            lambda d: d["action"] == "resume" and d["activity"] == "quiz", timeout=30
        )
        assert resumed["reason"] == "agenda"


def _seconds(iso_time: str) -> float:
    return datetime.fromisoformat(iso_time.replace("Z", "+00:00")).timestamp()


def test_a_perception_module_whose_token_disappears_is_missing(tmp_path: Path) -> None:
    """Missing perception is "unknown", not "nobody": the session outlives it for the
    grace (here 3 s), then ends with reason input_missing."""
    with running_daemon(tmp_path, "perception_grace_s = 3.0\n") as (daemon, session):
        states = Collector(session, "robots/mini/dms/state")
        perception = client_session(daemon.port)
        try:
            token = perception.liveliness().declare_token("robots/mini/alive/perception/user")
            put(perception, "perception/user", ANN_READY)
            states.wait_for(
                lambda s: s["inputs"].get("perception/user") == "ok" and s["user"] is not None
            )
            mark = states.mark()  # "missing" before ann came too: look only after the token goes
            token.undeclare()
            gone = states.wait_for(
                lambda s: s["inputs"].get("perception/user") == "missing", start=mark
            )
            user = {k: gone["user"][k] for k in ("id", "ready")}
            assert user == {"id": "ann", "ready": False}, "the user is unknown, not gone"
            ended = states.wait_for(lambda s: s["user"] is None, timeout=20, start=mark)
            assert ended["inputs"]["perception/user"] == "missing"
            kept = _seconds(ended["time"]) - _seconds(gone["time"])
            assert 2.4 <= kept <= 4.0, f"the session outlived its perception {kept:.1f} s"
        finally:
            perception.close()


BAD_PAYLOADS: list[tuple[str, bytes]] = [
    ("perception/user", b"{not json"),
    ("perception/user", b'{"present": "yes"}'),
    ("perception/touch", b'{"part": "tail", "kind": "tap"}'),
    ("perception/speech", b'{"text": "hi", "confidence": 7}'),
    ("perception/screen", b"[]"),
    ("params/robot", b'{"batterylevel": {"deep": 1}}'),
    ("params/env", b'"just a string"'),
    ("request", b'{"action": "start", "activity": "karaoke"}'),
    ("robot/feedback", b'{"id": 5}'),
    ("perception/speech", b'{"text": "' + b"a" * 1_000_000 + b'", "confidence": 1}'),
    ("perception/user", b"[" * 100_000 + b"]" * 100_000),
]


def test_malformed_payloads_are_reported_and_change_nothing(tmp_path: Path) -> None:
    with running_daemon(tmp_path) as (_daemon, session):
        errors = Collector(session, "robots/mini/dms/errors")
        states = Collector(session, "robots/mini/dms/state")
        before = states.wait_for(lambda s: s["activity"] is not None)
        for key, raw in BAD_PAYLOADS:
            put(session, key, raw)
        reports = errors.wait_count(len(BAD_PAYLOADS), timeout=15)
        assert sorted(r["key"] for r in reports) == sorted(k for k, _ in BAD_PAYLOADS)
        assert all(r["error"] and r["time"].endswith("Z") for r in reports)
        mark = states.mark()
        after = states.wait_count(mark + 4)[-4:]
        assert all(
            s["user"] is None and s["activity"]["name"] == before["activity"]["name"] for s in after
        )
        spans = [_ts(b) - _ts(a) for a, b in itertools.pairwise(after)]
        assert all(0.3 <= s <= 0.7 for s in spans), spans


def test_sigterm_stops_the_activity_and_exits_zero(tmp_path: Path) -> None:
    daemon = DaemonProcess(tmp_path)
    session = client_session(daemon.port)
    try:
        daemon.start(session)
        decisions = Collector(session, "robots/mini/dms/decision")
        put(session, "request", {"action": "start", "activity": "dance", "by": "test"})
        decisions.wait_for(lambda d: d["activity"] == "dance" and d["action"] == "start")
        with token_deleted(session, "robots/mini/alive/dms"):
            assert daemon.terminate() == 0
        decisions.wait_for(lambda d: d["action"] == "cancel" and d["reason"] == "shutdown")
    finally:
        daemon.kill()
        session.close()


def test_a_crash_in_native_code_leaves_every_threads_stack_in_the_log(tmp_path: Path) -> None:
    """A segmentation fault (here sent as a signal) ends the daemon, and its log says
    where the threads were, in Python, rather than nothing at all.

    The threads are written newest first, and reading the stack of one busy in native
    code can end the dump early (the training that starts at ready reads the store): so
    the log is asked for a Python frame, not for the main loop's in particular."""
    with running_daemon(tmp_path) as (daemon, session):
        assert daemon.proc is not None
        Collector(session, "robots/mini/dms/state").wait_count(1)  # the loop is running
        daemon.proc.send_signal(signal.SIGSEGV)
        assert daemon.proc.wait(20) == -signal.SIGSEGV
        log = daemon.log.read_text()
        assert "Fatal Python error: Segmentation fault" in log, log[-2000:]
        assert re.search(r'File "[^"]+\.py", line \d+ in \w+', log), log[-2000:]


def test_a_restart_keeps_profiles(tmp_path: Path) -> None:
    port_daemon = DaemonProcess(tmp_path, extra_config=SERVE_PROFILES)
    session = client_session(port_daemon.port)
    try:
        port_daemon.start(session)
        states = Collector(session, "robots/mini/dms/state")
        put(
            session,
            "perception/user",
            {"present": True, "user_id": "bob", "ready": True, "engagement": None},
        )
        states.wait_for(lambda s: (s["user"] or {}).get("id") == "bob")
        gone = threading.Event()
        sub = session.liveliness().declare_subscriber(
            "robots/mini/alive/dms",
            lambda sample: gone.set() if sample.kind == zenoh.SampleKind.DELETE else None,
        )
        assert port_daemon.terminate() == 0
        assert gone.wait(10)
        sub.undeclare()
        port_daemon.start(session)
        replies = query(session, "users/bob")
        assert replies and replies[0][0], replies
        listing = query(session, "users/*")
        assert "bob" in listing[0][1]["users"]
        bad = query(session, "users/bob smith\u202e")
        assert bad and not bad[0][0] and "U+202E" in bad[0][1]["error"], bad
    finally:
        port_daemon.kill()
        session.close()


def test_personal_data_is_not_served_unless_the_configuration_says_so(tmp_path: Path) -> None:
    with running_daemon(tmp_path) as (_daemon, session):
        states = Collector(session, "robots/mini/dms/state")
        put(session, "perception/user", {"present": True, "user_id": "bob", "ready": True})
        states.wait_for(lambda s: (s["user"] or {}).get("id") == "bob")
        for key in ("users/bob", "users/*", "agenda/bob", "agenda/*"):
            replies = query(session, key)
            assert replies and not replies[0][0], (key, replies)
            assert "serve_profiles" in replies[0][1]["error"], replies
