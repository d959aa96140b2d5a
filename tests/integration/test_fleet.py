"""From outside: a care home's fleet, every part real.

A Zenoh router (``dms router``, a process), three daemons (``dms run``, each a process
with its own robot id, connected to the router) and one PostgreSQL database (the
server CI starts; skipped with the reason where there is none). The test's session is
a peer of the router: it plays each robot's perception and a caregiver's app.

Ann visits the hall, then the garden, then the lounge, and what each robot learns is
there at the next; two robots serve her at once and lose nothing; a reminder due while
two robots see her is delivered once; the router is killed and restarted mid-session
and every daemon is heard again; a killed daemon's token goes at once.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from datetime import UTC, datetime, timedelta
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
)
from tests.postgres import POSTGRES_URL, fresh_schema

pytestmark = [
    pytest.mark.timeout(400),
    pytest.mark.integration,
    pytest.mark.skipif(POSTGRES_URL is None, reason="DMS_TEST_POSTGRES_URL is not set"),
]

ROBOTS = ("hall", "garden", "lounge")
FLEET_CONFIG = (  # the robot chooses for Ann (no menu), and profiles are served
    "user_initiative = { high = 0.0, moderate = 0.0, unknown = 0.0, low = 0.0 }\n"
    "[privacy]\nserve_profiles = true\n"
)


def _ann(present: bool) -> dict[str, Any]:
    return {"present": present, "user_id": "ann" if present else None, "ready": present}


def _dms(*args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "dms.cli", *args],
        capture_output=True,
        text=True,
        timeout=120,
        env=env or dict(os.environ),
        check=False,
    )


class Router:
    """``dms router`` in a subprocess on one loopback port; started again on the same
    port after a kill. Ready when it says it listens."""

    def __init__(self, port: int) -> None:
        self.port = port
        self.proc: subprocess.Popen[str] | None = None

    def start(self) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "dms.cli", "router", "--listen", f"tcp/127.0.0.1:{self.port}"],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
        )
        StderrLines(self.proc).wait_for("listening on")

    def kill(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(10)


@contextmanager
def _fleet(tmp: Path) -> Iterator[tuple[Router, zenoh.Session, dict[str, DaemonProcess], str]]:
    with fresh_schema("fleet") as url, ExitStack() as stack:
        upgraded = _dms("db", "upgrade", "--db", url)
        assert upgraded.returncode == 0, upgraded.stderr
        router = Router(free_port())
        router.start()
        stack.callback(router.kill)
        session = client_session(router.port)
        stack.callback(session.close)
        daemons: dict[str, DaemonProcess] = {}
        for robot in ROBOTS:
            folder = tmp / robot
            folder.mkdir()
            daemon = DaemonProcess(
                folder,
                extra_config=FLEET_CONFIG,
                extra_args=("--connect", f"tcp/127.0.0.1:{router.port}"),
                robot_id=robot,
                db=url,
                session_questions=1,  # each robot asks Ann one opening question
            )
            daemons[robot] = daemon
            stack.callback(daemon.kill)
        starters = [threading.Thread(target=d.start, args=(session,)) for d in daemons.values()]
        for thread in starters:
            thread.start()
        for thread in starters:
            thread.join()
        for robot, daemon in daemons.items():
            assert daemon.proc is not None and daemon.proc.poll() is None, robot
        yield router, session, daemons, url


class RobotCollector(Collector):
    """A Collector of one key over every robot; each message gains ``_robot``."""

    def _on(self, sample: zenoh.Sample) -> None:
        message = json.loads(sample.payload.to_bytes())
        message["_robot"] = str(sample.key_expr).split("/")[1]
        with self._cond:
            self.messages.append(message)
            self._cond.notify_all()


def _run_and_cancel(
    session: zenoh.Session, decisions: Collector, robot: str, activity: str
) -> dict[str, Any]:
    """Ann asks ``robot`` for ``activity``, then stops it herself; the cancel decision."""
    mark = decisions.mark()
    put(session, "request", {"action": "start", "activity": activity, "by": "ann"}, robot)
    decisions.wait_for(
        lambda d: d["_robot"] == robot and d["action"] == "start" and d["activity"] == activity,
        start=mark,
        timeout=30,
    )
    put(session, "request", {"action": "cancel", "activity": activity, "by": "ann"}, robot)
    return decisions.wait_for(
        lambda d: d["_robot"] == robot and d["action"] == "cancel" and d["activity"] == activity,
        start=mark,
        timeout=30,
    )


def _answer_the_opening_question(
    session: zenoh.Session, decisions: Collector, commands: Collector, robot: str, since: int
) -> dict[str, Any]:
    """Ann answers the one question ``robot`` asks her (from command ``since`` on): the
    first choice its screen shows, or her name. The question closed, the robot chooses
    for her: that decision (the answer was taken in its tick or before)."""
    commands.wait_for(
        lambda c: c["_robot"] == robot and c["channel"] == "speech" and "?" in str(c["args"]),
        start=since,
        timeout=30,
    )
    shown = [
        c["args"]["choices"]
        for c in commands.messages[since:]
        if c["_robot"] == robot and c["channel"] == "screen" and c["args"].get("choices")
    ]
    choices = shown[-1] if shown else ["Ann"]
    mark = decisions.mark()
    put(session, "perception/speech", {"text": str(choices[0]), "confidence": 0.95}, robot)
    return decisions.wait_for(
        lambda d: d["_robot"] == robot and d["action"] == "start", start=mark, timeout=30
    )


def _stored(states: Collector, robot: str, after: dict[str, Any]) -> None:
    """Until ``robot`` publishes, after decision ``after``'s tick, a state with no write
    pending: what that tick and the ones before it wrote is in the database."""
    _wait_state(states, robot, lambda s: s["tick"] > after["tick"] and s["pending_writes"] == 0)


def _answered(export: dict[str, Any]) -> list[str]:
    return [a["question"] for a in export["answers"]]


def _export(session: zenoh.Session, robot: str) -> dict[str, Any]:
    replies = query(session, "users/ann", robot=robot)
    assert replies and replies[0][0], replies
    body = replies[0][1]
    assert isinstance(body, dict)
    return body


def _wait_state(states: Collector, robot: str, predicate: Any, start: int = 0) -> dict[str, Any]:
    return states.wait_for(lambda s: s["robot"] == robot and predicate(s), start=start, timeout=30)


def test_a_care_home_fleet(tmp_path: Path) -> None:
    with _fleet(tmp_path) as (router, session, daemons, url):
        decisions = RobotCollector(session, "robots/*/dms/decision")
        commands = RobotCollector(session, "robots/*/robot/command")
        states = Collector(session, "robots/*/dms/state")
        errors = Collector(session, "robots/*/dms/errors")

        # Ann walks from the hall to the garden to the lounge; each robot sees her in turn.
        visits = [("hall", "jokes"), ("garden", "weather"), ("lounge", "sayings")]
        for index, (robot, activity) in enumerate(visits):
            if index:  # she leaves the last robot: its session ends there
                left = visits[index - 1][0]
                put(session, "perception/user", _ann(False), left)
                _wait_state(states, left, lambda s: s["user"] is None)
            since = commands.mark()
            put(session, "perception/user", _ann(True), robot)
            _wait_state(states, robot, lambda s: (s["user"] or {}).get("id") == "ann")
            chosen = _answer_the_opening_question(session, decisions, commands, robot, since)
            _stored(states, robot, chosen)
            assert len(_answered(_export(session, robot))) == index + 1, (
                f"Ann's answer at {robot} was not stored"
            )
            _stored(states, robot, _run_and_cancel(session, decisions, robot, activity))
            after = ROBOTS[(index + 1) % len(ROBOTS)]
            seen = _export(session, after)
            assert _asked(seen) == [a for _, a in visits[: index + 1]], (
                f"what {robot} recorded is not there at the next robot"
            )
            answered = _answered(seen)
            assert len(answered) == index + 1, f"{robot}'s answer is not there at {after}"
            assert len(set(answered)) == len(answered), f"a question was asked again: {answered}"
        put(session, "perception/user", _ann(False), "lounge")

        # Two robots serve Ann at the same moment: every run is stored, no write refused.
        for robot in ("hall", "garden"):
            put(session, "perception/user", _ann(True), robot)
            _wait_state(states, robot, lambda s: (s["user"] or {}).get("id") == "ann")
        before = _asked(_export(session, "lounge"))
        runs = 4

        last: dict[str, dict[str, Any]] = {}

        def serve(robot: str, activity: str) -> None:
            for _ in range(runs):
                last[robot] = _run_and_cancel(session, decisions, robot, activity)

        workers = [
            threading.Thread(target=serve, args=pair)
            for pair in (("hall", "jokes"), ("garden", "news"))
        ]
        for worker in workers:
            worker.start()
        for worker in workers:
            worker.join()
        for robot, cancel in last.items():
            _stored(states, robot, cancel)
        added_runs = _asked(_export(session, "lounge"))[len(before) :]
        assert sorted(added_runs) == ["jokes"] * runs + ["news"] * runs, (
            f"a concurrent write was lost: {added_runs}"
        )
        refused = [e for e in errors.messages if "refused" in json.dumps(e)]
        assert not refused, refused

        # A reminder due while the hall and the garden both see her: delivered once.
        due = datetime.now(UTC) + timedelta(seconds=8)
        added = _dms(
            "agenda",
            "add",
            "--user",
            "ann",
            "--reminder",
            "Time for your pills, Ann.",
            "--at",
            due.strftime("%Y-%m-%dT%H:%M:%S"),
            "--db",
            url,
        )
        assert added.returncode == 0, added.stderr
        mark = decisions.mark()

        def notification(d: dict[str, Any]) -> bool:
            return bool(d["action"] == "start" and d["activity"] == "notification")

        decisions.wait_for(notification, start=mark, timeout=120)
        state_mark = states.mark()
        horizon = (due + timedelta(seconds=15)).timestamp()
        for robot in ("hall", "garden"):
            _wait_state(states, robot, lambda s: _time(s) > horizon, start=state_mark)
        by = [d["_robot"] for d in decisions.messages[mark:] if notification(d)]
        assert by in (["hall"], ["garden"]), f"delivered by {by}"

        # The router is killed and restarted mid-session: every daemon is heard again.
        router.kill()
        router.start()
        restarted = states.mark()
        for robot in ROBOTS:
            _wait_state(states, robot, lambda s: True, start=restarted)

        # The fleet's status lists every robot, with Ann at the hall.
        listing = _dms("fleet", "status", "--connect", f"tcp/127.0.0.1:{router.port}", "--json")
        assert listing.returncode == 0, listing.stderr
        rows = {row["robot"]: row for row in map(json.loads, listing.stdout.splitlines())}
        assert set(rows) == set(ROBOTS)
        assert rows["hall"]["user"] == rows["garden"]["user"] == "ann"
        assert rows["lounge"]["user"] is None

        # A robot dies: its token goes, and the others see it at once.
        gone = threading.Event()
        watch = session.liveliness().declare_subscriber(
            "robots/lounge/alive/dms",
            lambda sample: gone.set() if sample.kind == zenoh.SampleKind.DELETE else None,
        )
        proc = daemons["lounge"].proc
        assert proc is not None
        killed = time.monotonic()
        proc.send_signal(signal.SIGKILL)
        assert gone.wait(10), "the dead robot's token stayed"
        took = time.monotonic() - killed
        watch.undeclare()
        assert took < 3.0, f"the token went {took:.2f} s after the kill"


def _time(state: dict[str, Any]) -> float:
    return datetime.fromisoformat(str(state["time"]).replace("Z", "+00:00")).timestamp()


def _asked(export: dict[str, Any]) -> list[str]:
    """The activities Ann asked for herself, in the order they ran (the robot's own
    choices for her in between are left out)."""
    return [a["activity"] for a in export["activities"] if a["chosen_by"] == "user"]
