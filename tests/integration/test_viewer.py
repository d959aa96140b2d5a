"""``dms view`` as a real process beside a real daemon, on 127.0.0.1.

The first test reads the viewer's event stream as a script would; the second drives the
page in Debian's Chromium with Playwright and saves docs/viewer.png. Every wait is for an
event, a message or a page change, with a deadline.
"""

from __future__ import annotations

import itertools
import json
import re
import subprocess
import sys
import threading
import urllib.parse
import urllib.request
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import Any

import pytest
import zenoh

from dms.viewer.model import LiveModel
from dms.viewer.source import BusSource
from tests.integration.harness import (
    Collector,
    DaemonProcess,
    client_session,
    put,
    query,
    running_daemon,
)
from tests.integration.viewer_harness import (
    CHROMIUM,
    CHROMIUM_ARGS,
    EventStream,
    at,
    browser_missing,
    running_viewer,
)

SCREENSHOT = Path(__file__).resolve().parents[2] / "docs" / "viewer.png"
QUIZ = {"action": "start", "activity": "quiz", "by": "test"}
ANN_LEFT = {  # ann, her face 30° to the robot's left (atan2(0.35, 0.6)), a little below
    "present": True,
    "user_id": "ann",
    "ready": True,
    "face": {"position": {"x": 0.6, "y": 0.35, "z": 0.35}},
}


@contextmanager
def perceiving(
    session: zenoh.Session, message: dict[str, Any], every_s: float = 0.2
) -> Iterator[None]:
    """A perception module: ``perception/user`` every ``every_s`` while the block runs (a
    face is live only while it is refreshed)."""
    stop = threading.Event()

    def run() -> None:
        while True:
            put(session, "perception/user", message)
            if stop.wait(every_s):
                return

    thread = threading.Thread(target=run, name="perception", daemon=True)
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join(5)


def _activity(state: dict[str, Any]) -> str | None:
    return (state.get("activity") or {}).get("name")


@pytest.mark.integration
def test_the_viewer_streams_state_structure_and_decisions(tmp_path: Path) -> None:
    with running_daemon(tmp_path) as (daemon, session), running_viewer(daemon.port) as url:
        page = urllib.request.urlopen(url, timeout=10).read().decode()
        assert "static/uPlot.iife.min.js" in page and "static/viewer.js" in page
        for asset in ("uPlot.iife.min.js", "uPlot.min.css", "viewer.js", "viewer.css"):
            with urllib.request.urlopen(at(url, f"static/{asset}"), timeout=10) as response:
                assert response.status == 200 and response.read()

        lingering = EventStream(url)  # a page still open when the viewer stops
        stream = EventStream(url)
        try:
            snapshot = stream.wait_for("snapshot", lambda _s: True)
            assert snapshot["history_s"] == 3600.0
            if not snapshot["robots"].get("mini", {}).get("alive"):
                stream.wait_for("robot", lambda r: r["robot"] == "mini" and r["alive"])
            put(session, "request", QUIZ)
            decision = stream.wait_for("decision", lambda d: d["decision"]["activity"] == "quiz")
            assert decision["decision"]["action"] == "start"
            state = stream.wait_for("state", lambda s: _activity(s["state"]) == "quiz")
            assert state["robot"] == "mini"
            # The drives' thresholds, from the daemon's dms/config (the shipped ones here).
            drawn = stream.wait_for("state", lambda s: s["thresholds_source"] == "config")
            assert drawn["thresholds"] == {"rest": 60.0, "social": 60.0, "play": 50.0}
            structure = stream.wait_for(
                "structure", lambda s: (s["structure"] or {}).get("activity") == "quiz"
            )
            root = structure["structure"]["structure"]["root"]
            assert root["name"] == "quiz" and root["initial"] == "INTRO"
            # The simulated Mini's joints, at most four times a second.
            body = stream.wait_for("body", lambda b: b["robot"] == "mini" and b["joints"])
            joints = sorted(body["joints"]["positions"])
            assert joints == ["head", "hip", "left_arm", "neck", "right_arm"]
            put(session, "perception/touch", {"part": "knee", "kind": "tap"})
            error = stream.wait_for("report", lambda e: e["error"]["key"] == "perception/touch")
            assert "knee" in error["error"]["error"] or "part" in error["error"]["error"]
        finally:
            stream.close()

        with urllib.request.urlopen(at(url, "api/snapshot"), timeout=10) as response:
            mini = json.loads(response.read())["robots"]["mini"]
    lingering.close()
    assert mini["alive"] and _activity(mini["state"]) == "quiz"
    assert any(d["activity"] == "quiz" for d in mini["decisions"])
    assert mini["samples"] and set(mini["samples"][-1][1]) == set(mini["thresholds"])
    agenda = mini["agenda"]
    assert agenda is not None and "serve_profiles" in agenda["error"]  # not served by default


@pytest.mark.integration
@pytest.mark.skipif(browser_missing() is not None, reason=str(browser_missing()))
def test_the_page_shows_the_activity_and_follows_a_request_in_chromium(tmp_path: Path) -> None:
    from playwright.sync_api import expect, sync_playwright

    with (
        running_daemon(tmp_path) as (daemon, session),
        running_viewer(daemon.port) as url,
        sync_playwright() as playwright,
        ExitStack() as perception,
    ):
        states = Collector(session, "robots/mini/dms/state")
        first = states.wait_for(lambda s: s["activity"] is not None)
        browser = playwright.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
        try:
            page = browser.new_page(viewport={"width": 1400, "height": 1000})
            page.goto(url)
            expect(page.locator("#link")).to_have_text("live", timeout=20_000)
            expect(page.locator("button.robot.alive[data-robot=mini]")).to_be_visible()

            # The running activity, and its active state highlighted in the drawing.
            running = first["activity"]
            expect(page.locator("#activity-name")).to_have_text(running["name"], timeout=10_000)
            expect(page.locator("#activity-state")).to_have_text(running["state"])
            active = page.locator("#machine g.state.active")
            expect(active).to_have_count(1, timeout=10_000)
            expect(active).to_have_attribute("data-path", running["state"])

            # At rest, the head looks straight ahead.
            gaze = page.get_by_test_id("gaze")
            expect(gaze).to_have_text("looking straight ahead; hip 0°", timeout=10_000)

            # A user arrives, her face to the left; an app's request: the page follows
            # within 2 s, and the quiz turns the head toward her within a few seconds.
            perception.enter_context(perceiving(session, ANN_LEFT))
            expect(page.locator("#user")).to_have_text("ann (ready)", timeout=10_000)
            put(session, "request", QUIZ)
            expect(page.locator("#activity-name")).to_have_text("quiz", timeout=2_000)
            started = page.locator("#decisions li[data-action=start][data-activity=quiz]")
            expect(started).to_have_count(1)
            # Her face is 30° to the left (the head turns there: from 25° to 35° on the
            # page), a little below the head.
            toward_ann = re.compile(r"^looking (2[5-9]|3[0-5])° left, \d+° down; hip ")
            expect(gaze).to_have_text(toward_ann, timeout=5_000)
            expect(page.get_by_test_id("aim")).to_contain_text("user")

            # Inside the quiz: a nested state is highlighted, with the states around it.
            asking = states.wait_for(
                lambda s: "/ASK" in ((s["activity"] or {}).get("state") or ""), timeout=60.0
            )
            path = asking["activity"]["state"]
            expect(page.locator("#machine g.state.active")).to_have_attribute(
                "data-path", path, timeout=5_000
            )
            for outer in ("GAME", "GAME/ROUNDS", "GAME/ROUNDS/ROUND"):
                assert page.locator(f'#machine g.state.on-path[data-path="{outer}"]').count() == 1

            # A rejected input's error quotes it: shown as text, never as HTML.
            hostile = "<img src=x onerror=document.title='pwned'>"
            put(session, "request", {"action": "start", "activity": hostile})
            expect(page.locator("#errors li").first).to_contain_text(hostile)
            assert page.locator("#errors img").count() == 0 and page.title() == "dms viewer"
            expect(page.locator("#chart-drives canvas").first).to_be_visible()
            expect(page.locator("#link")).to_have_text("live")  # the stream never broke
            page.screenshot(path=str(SCREENSHOT), full_page=True)
        finally:
            browser.close()
    assert SCREENSHOT.stat().st_size > 10_000


NESTED_DANCE = """
name: dance
description: A dance whose moves hold a concurrence of their own (two levels of them).
outcomes: [done, preempted]
states:
  DANCE:
    concurrence:
      outcomes: [done]
      default_outcome: done
      outcome_map: {done: {MUSIC: done}}
      states:
        MUSIC:
          wait: {seconds: 120}
        MOVES:
          state_machine:
            outcomes: [done]
            states:
              WARM_UP:
                wait: {seconds: 0.5}
                transitions: {done: BOTH}
              BOTH:
                concurrence:
                  outcomes: [done]
                  default_outcome: done
                  states:
                    LEFT:
                      wait: {seconds: 100}
                    RIGHT:
                      wait: {seconds: 100}
                transitions: {done: done}
    transitions: {done: done, preempted: preempted}
"""
SHIPPED_BEHAVIORS = Path(__file__).resolve().parents[2] / "activities" / "behaviors"


@pytest.mark.integration
@pytest.mark.skipif(browser_missing() is not None, reason=str(browser_missing()))
def test_the_page_lights_every_branch_of_nested_concurrences(tmp_path: Path) -> None:
    from playwright.sync_api import expect, sync_playwright

    behaviors = tmp_path / "behaviors"
    behaviors.mkdir()
    for shipped in SHIPPED_BEHAVIORS.glob("*.yaml"):
        (behaviors / shipped.name).write_text(shipped.read_text())
    (behaviors / "dance.yaml").write_text(NESTED_DANCE)
    folder = f'\n[behaviors]\nfolder = "{behaviors}"\n'
    with (
        running_daemon(tmp_path, folder) as (daemon, session),
        running_viewer(daemon.port) as url,
        sync_playwright() as playwright,
    ):
        states = Collector(session, "robots/mini/dms/state")
        browser = playwright.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
        try:
            page = browser.new_page(viewport={"width": 1400, "height": 1000})
            page.goto(url)
            expect(page.locator("#link")).to_have_text("live", timeout=20_000)
            put(session, "request", {"action": "start", "activity": "dance", "by": "test"})
            both = "DANCE/MUSIC,MOVES/BOTH/LEFT,RIGHT"  # each "," opens a concurrence's branch
            states.wait_for(lambda s: (s["activity"] or {}).get("state") == both, timeout=30.0)
            expect(page.locator("#activity-state")).to_have_text(both, timeout=5_000)
            active = page.locator("#machine g.state.active")
            expect(active).to_have_count(3, timeout=10_000)
            lit = sorted(active.nth(i).get_attribute("data-path") or "" for i in range(3))
            assert lit == ["DANCE/MOVES/BOTH/LEFT", "DANCE/MOVES/BOTH/RIGHT", "DANCE/MUSIC"]
            for outer in ("DANCE", "DANCE/MOVES", "DANCE/MOVES/BOTH"):
                on_path = page.locator(f'#machine g.state.on-path[data-path="{outer}"]')
                expect(on_path).to_have_count(1)
            assert page.locator('#machine g.state.active[data-path="DANCE/MOVES"]').count() == 0
        finally:
            browser.close()


@pytest.mark.integration
@pytest.mark.skipif(browser_missing() is not None, reason=str(browser_missing()))
def test_a_page_opened_mid_session_shows_what_came_before(tmp_path: Path) -> None:
    """The decisions made before the viewer started, and the daemon's own start time."""
    from playwright.sync_api import expect, sync_playwright

    with running_daemon(tmp_path) as (daemon, session):
        states = Collector(session, "robots/mini/dms/state")
        decisions = Collector(session, "robots/mini/dms/decision")
        put(session, "request", QUIZ)
        decisions.wait_for(lambda d: d["activity"] == "quiz" and d["action"] == "start")
        started = states.wait_for(lambda s: "started" in s)["started"]
        with running_viewer(daemon.port) as url, sync_playwright() as playwright:
            browser = playwright.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
            try:
                page = browser.new_page(viewport={"width": 1400, "height": 1000})
                page.goto(url)
                expect(page.locator("#link")).to_have_text("live", timeout=20_000)
                before = page.locator("#decisions li[data-action=start][data-activity=quiz]")
                expect(before).to_have_count(1, timeout=10_000)
                robot = page.locator("#robot-name")
                expect(robot).to_have_attribute("title", f"the daemon started at {started}")
                expect(robot).to_contain_text("alive since")
                expect(robot).not_to_contain_text("seen by the viewer")
            finally:
                browser.close()


@pytest.mark.integration
def test_the_viewer_refuses_bad_input_in_one_line(tmp_path: Path) -> None:
    dms = [sys.executable, "-m", "dms.cli", "view"]
    cases = [
        ([*dms, "--robot", "Not/Valid"], "--robot"),
        ([*dms, "--connect", "tcp/127.0.0.1:9", "--port", "0"], "cannot open the Zenoh session"),
        ([*dms, "--zenoh-config", str(tmp_path / "missing.json5")], "--zenoh-config"),
        ([*dms, "--port", "70000"], "--port"),
    ]
    for argv, expected in cases:
        done = subprocess.run(argv, capture_output=True, text=True, timeout=60)
        assert done.returncode != 0, argv
        lines = done.stderr.strip().splitlines()
        assert expected in done.stderr, (argv, done.stderr)
        assert "Traceback" not in done.stderr and len([ln for ln in lines if ln.strip()]) <= 8


@pytest.mark.integration
def test_a_port_in_use_is_one_line(tmp_path: Path) -> None:
    with running_daemon(tmp_path) as (daemon, _session), running_viewer(daemon.port) as url:
        port = str(urllib.parse.urlsplit(url).port)
        done = subprocess.run(
            [
                sys.executable,
                "-m",
                "dms.cli",
                "view",
                "--connect",
                f"tcp/127.0.0.1:{daemon.port}",
                "--port",
                port,
            ],
            capture_output=True,
            text=True,
            timeout=60,
        )
    assert done.returncode == 1
    assert done.stderr.strip().splitlines() == [
        line for line in done.stderr.strip().splitlines() if line.startswith("dms: cannot serve")
    ]


@pytest.mark.integration
def test_the_agenda_shows_when_the_daemon_serves_it(tmp_path: Path) -> None:
    serve = "[privacy]\nserve_profiles = true\n"
    with running_daemon(tmp_path, serve) as (daemon, session):
        decisions = Collector(session, "robots/mini/dms/decision")
        put(session, "perception/user", {"present": True, "user_id": "ann", "ready": True})
        decisions.wait_for(lambda d: d["reason"] == "user_arrived")
        item = {"op": "add", "kind": "reminder", "text": "The doctor at five"}
        replies = query(session, "agenda/ann", {**item, "at": "2099-01-01T17:00:00", "tz": "UTC"})
        assert replies and replies[0][0], replies
        with running_viewer(daemon.port) as url:
            stream = EventStream(url)
            try:
                first = stream.wait_for("snapshot", lambda _s: True)
                agenda = (first["robots"].get("mini") or {}).get("agenda")
                if agenda is None:
                    agenda = stream.wait_for("agenda", lambda _a: True)["agenda"]
            finally:
                stream.close()
    assert [i["text"] for i in agenda["items"]] == ["The doctor at five"], agenda
    assert agenda["items"][0]["user_id"] == "ann"


@pytest.mark.integration
def test_one_viewer_watches_several_daemons_or_the_ones_named(tmp_path: Path) -> None:
    for robot in ("hall", "garden"):
        (tmp_path / robot).mkdir()
    daemons = [DaemonProcess(tmp_path / robot, robot_id=robot) for robot in ("hall", "garden")]
    sessions = []
    try:
        for daemon in daemons:
            sessions.append(client_session(daemon.port))
            daemon.start(sessions[-1])
        both = [f"--connect=tcp/127.0.0.1:{d.port}" for d in daemons][1:]
        first = daemons[0].port
        with running_viewer(first, *both) as url:
            _wait_alive(url, {"hall", "garden"})
            stream = EventStream(url)
            try:  # a daemon that stops is shown gone, the other stays
                stream.wait_for("snapshot", lambda _s: True)
                assert daemons[0].terminate() == 0
                gone = stream.wait_for("robot", lambda r: r["robot"] == "hall")
                assert not gone["alive"]
                with urllib.request.urlopen(at(url, "api/snapshot"), timeout=10) as response:
                    assert json.loads(response.read())["robots"]["garden"]["alive"]
            finally:
                stream.close()
        garden = tmp_path / "garden.json5"  # a Zenoh file instead of --connect
        garden.write_text(
            json.dumps(
                {
                    "mode": "peer",
                    "connect": {"endpoints": [f"tcp/127.0.0.1:{daemons[1].port}"]},
                    "listen": {"endpoints": []},
                    "scouting": {"multicast": {"enabled": False}},
                }
            )
        )
        with running_viewer(None, "--zenoh-config", str(garden), "--robot", "garden") as url:
            _wait_alive(url, {"garden"})
            with urllib.request.urlopen(at(url, "api/snapshot"), timeout=10) as response:
                assert list(json.loads(response.read())["robots"]) == ["garden"]
    finally:
        for daemon in daemons:
            daemon.kill()
        for session in sessions:
            session.close()


def _wait_alive(url: str, robots: set[str]) -> None:
    """Until the viewer's stream says each of ``robots`` is alive."""
    stream = EventStream(url)
    try:
        first = stream.wait_for("snapshot", lambda _s: True)
        alive = {robot for robot, view in first["robots"].items() if view["alive"]}
        for robot in robots - alive:
            stream.wait_for("robot", lambda r, robot=robot: r["robot"] == robot and r["alive"])
    finally:
        stream.close()


# ---------------------------------------------------------------------- the model alone


def _state(t: str, activity: str | None = "wait", path: str = "IDLE", **extra: Any) -> Any:
    return {
        "robot": "mini",
        "tick": 1,
        "time": t,
        "mode": "motivation",
        "user": None,
        "activity": (
            {"name": activity, "manager": "relax", "status": "running", "state": path}
            if activity
            else None
        ),
        "suspended": None,
        "motivation": {
            "dominant": None,
            "drives": {"rest": 20.0, "play": 30.0},
            "motivations": {"rest": 0.0, "play": 0.0},
            "wellbeing": 80.0,
        },
        "inputs": {},
        **extra,
    }


def test_the_model_keeps_one_point_a_second_over_an_hour() -> None:
    model = LiveModel(default_thresholds={"rest": 60.0, "play": 50.0, "social": 60.0})
    events: list[tuple[str, Any]] = []
    model.attach(lambda name, data: events.append((name, data)))
    for second in range(3700):
        for half in ("000", "500"):
            stamp = (
                f"2026-11-22T{10 + second // 3600:02d}:{second // 60 % 60:02d}:{second % 60:02d}"
            )
            model.on_state("mini", _state(f"{stamp}.{half}Z"))
    view = model.snapshot()["robots"]["mini"]
    assert len(view["samples"]) == 3601  # one a second, the last hour (both ends)
    assert view["samples"][-1][0] - view["samples"][0][0] == 3600.0
    assert view["thresholds"] == {"rest": 60.0, "play": 50.0}  # the drives the state names
    assert view["thresholds_source"] == "defaults"
    sampled = [d["sample"] for n, d in events if n == "state" and d["sample"] is not None]
    assert len(sampled) == 3700


def test_the_model_asks_for_the_structure_when_the_activity_changes() -> None:
    model = LiveModel()
    asked: list[tuple[str, str]] = []
    model.need = lambda robot, what: asked.append((robot, what))
    model.on_state("mini", _state("2026-11-22T10:00:00.000Z"))
    assert asked == [("mini", "behavior")]
    model.on_state("mini", _state("2026-11-22T10:00:00.500Z"))
    assert asked == [("mini", "behavior")], "asked once, not every tick"
    root = {"name": "wait", "states": [{"name": "IDLE"}], "initial": "IDLE"}
    model.set_structure("mini", {"activity": "wait", "structure": {"root": root}})
    model.on_state("mini", _state("2026-11-22T10:00:01.000Z"))
    model.on_state("mini", _state("2026-11-22T10:00:01.500Z", "quiz", "INTRO"))
    assert asked[-1] == ("mini", "behavior") and len(asked) == 2
    model.on_state("mini", _state("2026-11-22T10:00:02.000Z", None))
    assert model.snapshot()["robots"]["mini"]["structure"] is None


def test_the_model_reads_what_daemons_publish_loosely() -> None:
    model = LiveModel(robots=["mini"])
    state = BusSource._json(model.on_state)
    state("robots/mini/dms/state", b'["not", "an", "object"]')
    state("robots/mini/dms/state", b"not JSON")
    state("robots/mini/dms/state", b'{"motivation": {"drives": {"rest": NaN}}}')
    state("robots/other/dms/state", json.dumps(_state("2026-11-22T10:00:00.000Z")).encode())
    model.on_decision("mini", "nonsense")
    model.on_state("mini", _state("bad time", motivation={"drives": {"rest": "high"}}))
    model.on_token("robots/mini/alive/dms", True)
    model.on_token("robots/mini/alive/perception/user", True)
    model.on_token("robots/Bad!/alive/dms", True)
    snapshot = model.snapshot()
    assert list(snapshot["robots"]) == ["mini"]  # only the robot watched
    view = snapshot["robots"]["mini"]
    assert view["alive"] and view["tokens"] == ["perception/user"]
    assert view["samples"] == [] and view["decisions"] == []
    assert view["state"]["time"] == "bad time"  # shown as it came, charted nowhere
    json.dumps(snapshot, allow_nan=False)  # what the page gets is plain JSON


class _Clock:
    """A settable clock for the model (epoch seconds)."""

    def __init__(self) -> None:
        self.now = 1_800_000_000.0

    def __call__(self) -> float:
        return self.now


def _joints(neck: float, **more: float) -> dict[str, Any]:
    positions = {"hip": 0.0, "left_arm": 0.0, "right_arm": 0.0, "neck": neck, "head": 0.1}
    return {"positions": {**positions, **more}, "time": "2026-11-22T10:00:00.000Z"}


def test_the_model_sends_the_body_at_most_four_times_a_second() -> None:
    clock = _Clock()
    model = LiveModel(clock=clock)
    sent: list[tuple[float, Any]] = []
    model.attach(lambda name, data: sent.append((clock.now, data)) if name == "body" else None)
    start = clock.now
    for tenth in range(21):  # the head turns left for two seconds, joints ten times a second
        clock.now = start + tenth / 10
        model.on_joints("mini", _joints(neck=tenth * 0.05))
    times = [t for t, _ in sent]
    assert len(times) <= 9 and all(b - a >= 0.25 for a, b in itertools.pairwise(times))
    latest = model.snapshot()["robots"]["mini"]["joints"]["positions"]
    assert latest["neck"] == pytest.approx(1.0)  # the snapshot holds the last joints
    assert sent[-1][1]["joints"]["positions"]["neck"] < 1.0  # held back by the throttle

    clock.now += 0.5  # the next state sends what was held back, once
    model.on_state("mini", _state("2026-11-22T10:00:02.500Z"))
    assert sent[-1][1]["joints"]["positions"]["neck"] == pytest.approx(1.0)
    count = len(sent)
    for _ in range(5):  # a body at rest is not sent again
        clock.now += 0.5
        model.on_joints("mini", _joints(neck=1.0))
        model.on_state("mini", _state("2026-11-22T10:00:03.000Z"))
    assert len(sent) == count

    clock.now += 0.5  # an aim is news even when the joints did not move
    model.on_command(
        "mini",
        {"id": "c1", "channel": "aim", "action": "look_at", "args": {"frame": "user"}},
    )
    assert len(sent) == count + 1
    assert sent[-1][1]["aim"] == {"action": "look_at", "frame": "user", "time": clock.now}


def test_the_model_reads_joints_and_commands_loosely() -> None:
    model = LiveModel(robots=["mini"])
    joints = BusSource._json(model.on_joints)
    joints("robots/mini/robot/joints", b"not JSON")
    joints("robots/mini/robot/joints", b'{"positions": {"neck": NaN}}')
    model.on_joints("mini", ["neck", 0.5])
    model.on_joints("mini", {"positions": "neck"})
    model.on_joints("mini", {"positions": {"tail": 1.0, "neck": True, "head": "down"}})
    assert model.snapshot()["robots"].get("mini", {}).get("joints") is None
    model.on_joints("mini", {"positions": {"neck": 0.5, "tail": 1.0, "head": None}, "time": 7})
    model.on_joints("other", _joints(neck=0.2))  # not watched
    model.on_command("mini", {"channel": "speech", "action": "say", "args": {"text": "hi"}})
    model.on_command("mini", {"channel": "aim", "action": 3})
    view = model.snapshot()["robots"]["mini"]
    assert view["joints"] == {"positions": {"neck": 0.5}, "time": None}
    assert view["aim"] is None and list(model.snapshot()["robots"]) == ["mini"]
    model.on_command("mini", {"channel": "aim", "action": "look_at", "args": "user"})
    aim = model.snapshot()["robots"]["mini"]["aim"]
    assert aim["action"] == "look_at" and aim["frame"] is None  # no frame: back to neutral
    model.on_command("mini", {"channel": "aim", "action": "point_at", "args": {"frame": "x" * 999}})
    assert len(model.snapshot()["robots"]["mini"]["aim"]["frame"]) == 200
