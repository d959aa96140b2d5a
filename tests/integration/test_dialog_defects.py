"""Questions and menus against real daemons on real Zenoh (127.0.0.1): an activity chosen
on the screen during the opening question, a menu nobody answers, and a reminder due
while one robot of two waits in its menu.
"""

from __future__ import annotations

import json
import subprocess
import sys
import threading
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from datetime import datetime
from pathlib import Path
from typing import Any

import pytest
import zenoh

from tests.integration.harness import (
    Collector,
    DaemonProcess,
    StderrLines,
    client_session,
    free_port,
    put,
    query,
    running_daemon,
)

pytestmark = [pytest.mark.integration, pytest.mark.timeout(300)]

ANN_READY = {"present": True, "user_id": "ann", "ready": True, "engagement": 0.8}
BOB_READY = {"present": True, "user_id": "bob", "ready": True, "engagement": 0.8}
MENU_FIRST = "user_initiative = { high = 1.0, moderate = 1.0, unknown = 1.0, low = 1.0 }\n"
"""Every user has the initiative: the robot opens the menu."""
ROBOT_FIRST = "user_initiative = { high = 0.0, moderate = 0.0, unknown = 0.0, low = 0.0 }\n"
SERVE_PROFILES = "[privacy]\nserve_profiles = true\n"


def _ts(message: dict[str, Any]) -> float:
    return datetime.fromisoformat(message["time"].replace("Z", "+00:00")).timestamp()


def _is(action: str, activity: str) -> Any:
    return lambda d: d["action"] == action and d["activity"] == activity


def _remind(session: zenoh.Session, state: dict[str, Any], in_s: float, robot: str) -> None:
    """A reminder for Ann, due ``in_s`` after ``state`` (the daemon's clock)."""
    at = datetime.fromtimestamp(_ts(state) + in_s).isoformat()
    item = {"op": "add", "user_id": "ann", "kind": "reminder", "at": at, "tz": "UTC"}
    item["text"] = "Time for your pills"
    replies = query(session, "agenda/ann", item, robot=robot)
    assert replies and replies[0][0], replies


def test_a_screen_choice_during_the_name_question_starts_bingo(tmp_path: Path) -> None:
    daemon = DaemonProcess(tmp_path, session_questions=4)
    session = client_session(daemon.port)
    try:
        daemon.start(session)
        decisions = Collector(session, "robots/mini/dms/decision")
        states = Collector(session, "robots/mini/dms/state")
        states.wait_count(1)
        put(session, "perception/user", ANN_READY)
        asked = decisions.wait_for(lambda d: d["action"] == "ask", timeout=30)
        assert asked["reason"] == "general_question" and "name" in asked["detail"].lower()
        mark = decisions.mark()
        put(session, "perception/screen", {"choice": "bingo"})
        started = decisions.wait_for(lambda d: d["action"] == "start", start=mark, timeout=30)
        assert started["activity"] == "bingo"
        assert started["reason"] == "user_request" and started["chosen_by"] == "user"
        between = decisions.messages[mark : decisions.messages.index(started)]
        assert not [d for d in between if d["action"] == "ask"], between
        states.wait_for(lambda s: (s["activity"] or {}).get("name") == "bingo")
    finally:
        daemon.kill()
        session.close()


def test_an_unanswered_menu_ends_after_menu_timeout_as_user_not_answering(
    tmp_path: Path,
) -> None:
    config = MENU_FIRST + "menu_timeout_s = 4.0\n"
    with running_daemon(tmp_path, config) as (daemon, session):
        decisions = Collector(session, "robots/mini/dms/decision")
        states = Collector(session, "robots/mini/dms/state")
        states.wait_count(1)
        put(session, "perception/user", ANN_READY)
        menu = decisions.wait_for(_is("start", "menu"), timeout=30)
        ended = decisions.wait_for(_is("cancel", "menu"), timeout=30)
        assert "no answer in 4 s" in ended["detail"]
        assert _ts(ended) - _ts(menu) >= 4.0
        mark = decisions.messages.index(ended)
        nxt = decisions.wait_for(lambda d: d["action"] == "start", start=mark, timeout=30)
        assert nxt["chosen_by"] == "robot" and nxt["reason"] == "preference"
        assert daemon.terminate() == 0  # the session is stored, with its metrics

    export = ("sessions", "export", "--format", "json", "--db", daemon.db)
    exported = subprocess.run(
        [sys.executable, "-m", "dms.cli", *export],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert exported.returncode == 0, exported.stderr
    rows = json.loads(exported.stdout)
    assert [r["user"] for r in rows] == ["ann"]
    assert rows[0]["user_not_answering"] == 1


class _Router:
    """``dms router`` on a loopback port; ready when it says it listens."""

    def __init__(self) -> None:
        self.port = free_port()
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "dms.cli", "router", "--listen", f"tcp/127.0.0.1:{self.port}"],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
        )
        StderrLines(self.proc).wait_for("listening on")

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(10)


@contextmanager
def _two_robots(tmp: Path) -> Iterator[zenoh.Session]:
    """Robot ``hall`` (its users choose from the menu) and robot ``garden`` (it chooses
    for them), each with its own database, on one router."""
    with ExitStack() as stack:
        router = _Router()
        stack.callback(router.kill)
        session = client_session(router.port)
        stack.callback(session.close)
        daemons = []
        for robot, choice in (("hall", MENU_FIRST), ("garden", ROBOT_FIRST)):
            folder = tmp / robot
            folder.mkdir()
            daemon = DaemonProcess(
                folder,
                extra_config=choice + SERVE_PROFILES,
                extra_args=("--connect", f"tcp/127.0.0.1:{router.port}"),
                robot_id=robot,
            )
            stack.callback(daemon.kill)
            daemons.append(daemon)
        starters = [threading.Thread(target=d.start, args=(session,)) for d in daemons]
        for thread in starters:
            thread.start()
        for thread in starters:
            thread.join()
        for daemon in daemons:
            assert daemon.proc is not None and daemon.proc.poll() is None, daemon.robot_id
        yield session


def test_a_reminder_due_while_one_robot_of_two_waits_in_its_menu_is_said(
    tmp_path: Path,
) -> None:
    with _two_robots(tmp_path) as session:
        hall = Collector(session, "robots/hall/dms/decision")
        hall_states = Collector(session, "robots/hall/dms/state")
        said = Collector(session, "robots/hall/robot/command")
        garden = Collector(session, "robots/garden/dms/decision")
        put(session, "perception/user", ANN_READY, robot="hall")
        put(session, "perception/user", BOB_READY, robot="garden")
        hall.wait_for(_is("start", "menu"), timeout=30)
        garden.wait_for(lambda d: d["action"] == "start" and d["chosen_by"] == "robot")
        # the agenda takes items for users the robot has met: wait until it has met Ann
        state = hall_states.wait_for(
            lambda s: (
                (s["activity"] or {}).get("name") == "menu" and (s["user"] or {}).get("id") == "ann"
            ),
            timeout=30,
        )
        mark = hall.mark()
        _remind(session, state, 3.0, robot="hall")
        start = hall.wait_for(_is("start", "notification"), start=mark, timeout=30)
        before = hall.messages[mark : hall.messages.index(start)]
        assert [(d["action"], d["activity"]) for d in before] == [("cancel", "menu")], before
        assert start["reason"] == "agenda" and _ts(start) - _ts(state) < 3.0 + 5.0
        said.wait_for(
            lambda c: c["channel"] == "speech" and "pills" in str(c["args"].get("text", "")),
            timeout=30,
        )
        again = hall.wait_for(_is("start", "menu"), start=mark, timeout=30)
        assert "again" in (again["detail"] or "")
        assert not [d for d in garden.messages if d["activity"] == "notification"]
