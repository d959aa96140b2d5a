"""From outside: ``dms reachy`` driving the maker's simulated Reachy Mini for a real daemon.

One MuJoCo simulator (``reachy-mini-daemon --sim --headless --no-media`` through
``dms_reachy.simulator``, which keeps it off the network) is shared by the module, with
a daemon run with ``--robot zenoh`` and the bridge as a person starts it (``dms reachy``,
its environment made as the docs say). What the robot does is read back through the
SDK by ``dms_reachy.probe``, a plain client in the bridge's environment. Every wait is
for a message, a token, a log line or the probe's answer, with a deadline.
"""

from __future__ import annotations

import json
import math
import os
import re
import subprocess
import sys
import urllib.request
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import zenoh

from dms.kernel.messages import UserPerception
from dms.reachy_cli import prepare
from tests.integration.harness import (
    Collector,
    DaemonProcess,
    StderrLines,
    client_session,
    free_port,
    put,
    query,
    token_deleted,
    wait_token,
)
from tests.integration.test_ros2 import inet_sockets, off_loopback
from tests.integration.test_studio import running_studio, shipped_copy
from tests.integration.viewer_harness import CHROMIUM, CHROMIUM_ARGS, browser_missing

pytestmark = [pytest.mark.integration, pytest.mark.timeout(300)]
"""A simulator start and a reconnection under a loaded CI take longer than the 120 s default."""

WAIT_S = 60.0
"""The simulator starts in about 5 s; the margin is for a loaded CI machine."""
HEAD_ORIGIN_Z_M = 0.177
"""docs/reachy.md: the dms base frame's origin is this far below Reachy's world frame."""
APP_ROBOT = "app"
"""The robot id the dashboard's app carries (beside the bridge's ``mini``)."""
LINK = "ack_timeout_s = 3.0\noffline_after_unacked = 2\noffline_retry_max_s = 5.0\n"


@pytest.fixture(scope="module")
def bridge_python() -> Path:
    """The bridge's environment, made as docs/reachy.md says (CI makes it first)."""
    return prepare(echo=False)


class Simulator:
    """The maker's simulated Reachy Mini on a port of the test's own."""

    def __init__(self, python: Path, port: int, env: dict[str, str] | None = None) -> None:
        self.python, self.port = python, port
        self.env = {**os.environ, **(env or {})}
        """Its apps inherit it, as a robot's apps inherit its daemon's environment."""
        self.proc: subprocess.Popen[str] | None = None

    def start(self) -> None:
        self.proc = subprocess.Popen(
            [str(self.python), "-m", "dms_reachy.simulator", "--port", str(self.port)],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
            env=self.env,
        )
        self.log = StderrLines(self.proc)
        self.log.wait_for("Application startup complete", timeout=WAIT_S)

    def kill(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(20)


class Probe:
    """``python -m dms_reachy.probe``: one JSON line asked, one answered."""

    def __init__(self, python: Path, port: int) -> None:
        self.proc = subprocess.Popen(
            [str(python), "-m", "dms_reachy.probe", "--port", str(port)],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            text=True,
        )
        assert self.proc.stdout is not None
        ready = json.loads(self.proc.stdout.readline() or "{}")
        assert ready.get("ready"), ready

    def ask(self, **order: Any) -> dict[str, Any]:
        assert self.proc.stdin is not None and self.proc.stdout is not None
        self.proc.stdin.write(json.dumps(order) + "\n")
        self.proc.stdin.flush()
        answer: dict[str, Any] = json.loads(self.proc.stdout.readline())
        assert "error" not in answer, answer
        return answer

    def watch_announced(self, seconds: float) -> float:
        """Start a watch; returns once it samples, with when it began (monotonic)."""
        assert self.proc.stdin is not None and self.proc.stdout is not None
        self.proc.stdin.write(json.dumps({"op": "watch", "seconds": seconds, "announce": True}))
        self.proc.stdin.write("\n")
        self.proc.stdin.flush()
        return float(json.loads(self.proc.stdout.readline())["watching"])

    def result(self) -> dict[str, Any]:
        """The answer of the watch started last."""
        assert self.proc.stdout is not None
        answer: dict[str, Any] = json.loads(self.proc.stdout.readline())
        return answer

    def close(self) -> None:
        if self.proc.poll() is None:
            assert self.proc.stdin is not None
            self.proc.stdin.write('{"op": "quit"}\n')
            self.proc.stdin.flush()
            self.proc.wait(20)


class Setup:
    def __init__(
        self,
        session: zenoh.Session,
        sim: Simulator,
        probe: Probe,
        bridge: subprocess.Popen[str],
        bridge_log: StderrLines,
    ) -> None:
        self.session, self.sim, self.probe = session, sim, probe
        self.bridge, self.bridge_log = bridge, bridge_log
        self.daemon_port = 0
        self.listen()

    def listen(self) -> None:
        """Collectors for the test about to run: conftest closes each test's after it."""
        session = self.session
        self.commands = Collector(session, "robots/mini/robot/command")
        self.feedback = Collector(session, "robots/mini/robot/feedback")
        self.decisions = Collector(session, "robots/mini/dms/decision")
        self.states = Collector(session, "robots/mini/dms/state")
        self.errors = Collector(session, "robots/mini/dms/errors")
        self.joints = Collector(session, "robots/mini/robot/joints")

    def stop_bridge(self) -> None:
        if self.bridge.poll() is None:
            self.bridge.terminate()
            self.bridge.wait(20)

    def command(self, predicate: Any, start: int, timeout: float = 30.0) -> dict[str, Any]:
        return self.commands.wait_for(predicate, timeout=timeout, start=start)

    def status(self, command_id: str, status: str, timeout: float = 30.0) -> dict[str, Any]:
        return self.feedback.wait_for(
            lambda f: f["id"] == command_id and f["status"] == status, timeout=timeout
        )

    def request(self, action: str, activity: str | None = None) -> None:
        put(self.session, "request", {"action": action, "activity": activity, "by": "test"})

    def idle(self) -> None:
        """Nobody in front, whatever runs cancelled: wait until the robot only waits."""
        put(self.session, "perception/user", {"present": False})
        self.request("cancel")
        self.states.wait_for(
            lambda s: s["activity"] is None or s["activity"]["name"] == "wait",
            start=self.states.mark(),
            timeout=30,
        )


def start_bridge(daemon_port: int, sim_port: int) -> tuple[subprocess.Popen[str], StderrLines]:
    """``dms reachy`` as a person starts it."""
    argv = [sys.executable, "-m", "dms.cli", "reachy", "--connect"]
    argv += [f"tcp/127.0.0.1:{daemon_port}", "--host", "127.0.0.1", "--port", str(sim_port)]
    bridge = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    return bridge, StderrLines(bridge)


@pytest.fixture(scope="module")
def setup(bridge_python: Path, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Setup]:
    tmp = tmp_path_factory.mktemp("reachy")
    daemon = DaemonProcess(tmp, extra_config=LINK, extra_args=("--robot", "zenoh"))
    port = free_port()
    app_env = {"DMS_CONNECT": f"tcp/127.0.0.1:{daemon.port}", "DMS_ROBOT": APP_ROBOT}
    app_env.update(DMS_REACHY_HOST="127.0.0.1", DMS_REACHY_PORT=str(port))
    sim = Simulator(bridge_python, port, app_env)
    session = client_session(daemon.port)
    made: Setup | None = None
    try:
        sim.start()
        daemon.start(session)
        bridge, log = start_bridge(daemon.port, sim.port)
        made = Setup(session, sim, Probe(bridge_python, sim.port), bridge, log)
        wait_token(session, "robots/mini/alive/robot/feedback", timeout=WAIT_S)
        made.daemon_port = daemon.port
        yield made
    finally:
        if made is not None:
            made.probe.close()
            made.stop_bridge()
        daemon.kill()
        sim.kill()
        session.close()


@pytest.fixture(autouse=True)
def listening(setup: Setup) -> None:
    """The module's setup listens afresh for each test (its collectors of the test
    before were closed with it)."""
    setup.listen()


def test_an_activity_s_gesture_moves_the_simulated_head_and_antennas(setup: Setup) -> None:
    start = setup.commands.mark()
    setup.request("start", "presentation")  # it opens with a wave
    wave = setup.command(lambda c: c["args"].get("name") == "wave", start)
    setup.status(wave["id"], "started")
    seen = setup.probe.ask(op="watch", seconds=2.0)
    assert seen["high"]["left"] - seen["low"]["left"] > 0.4, seen  # the left antenna waves
    assert seen["high"]["roll"] - seen["low"]["roll"] > 0.08, seen  # the head leans
    setup.status(wave["id"], "done")
    # the joints come from the simulated robot: hip, neck and head, no arms
    joints = setup.joints.wait_for(lambda j: True, start=setup.joints.mark())
    assert set(joints["positions"]) == {"hip", "neck", "head"}
    setup.idle()


def test_the_simulator_the_bridge_and_the_probe_keep_to_loopback(setup: Setup) -> None:
    """No mDNS advertisement, no telemetry, no dataset check: every IP socket of the
    three processes is on loopback while the robot moves."""
    setup.joints.wait_count(setup.joints.mark() + 3, timeout=WAIT_S)
    for proc in (setup.sim.proc, setup.bridge, setup.probe.proc):
        assert proc is not None
        sockets = inet_sockets(proc.pid)  # `dms reachy` execs: its pid is the bridge's
        assert any(protocol.startswith("tcp") for protocol, *_ in sockets), sockets
        assert off_loopback(sockets) == [], sockets


def test_a_command_it_cannot_read_is_dropped_and_the_next_one_carried_out(setup: Setup) -> None:
    mark = setup.bridge_log.mark()
    put(setup.session, "robot/command", b"not json")
    setup.bridge_log.wait_for("robot/command ignored: not JSON", start=mark)
    # a duration that is no finite number: the gesture keeps its own (1.5 s)
    nod = b'{"id": "nod-1", "channel": "motion", "action": "gesture",'
    nod += b' "args": {"name": "nod", "duration_s": Infinity}}'
    put(setup.session, "robot/command", nod)
    started = setup.status("nod-1", "started")
    done = setup.status("nod-1", "done")
    assert started and done
    odd = {"id": "odd-1", "channel": "motion", "action": "gesture", "args": {"name": "moonwalk"}}
    put(setup.session, "robot/command", odd)
    failed = setup.status("odd-1", "failed")
    assert failed["detail"] == "unknown gesture 'moonwalk'"


def test_look_at_a_face_turns_the_head_toward_it(setup: Setup) -> None:
    face = (0.6, 0.25, 0.30)  # the dms base frame: x forward, y left, z up from the table
    user = {"present": True, "user_id": "ann", "ready": True}
    user["face"] = {"position": dict(zip("xyz", face, strict=True)), "orientation": None}
    put(setup.session, "perception/user", user)
    start = setup.commands.mark()
    setup.request("start", "quiz")  # it attends the person it plays with
    aim = setup.command(
        lambda c: c["channel"] == "aim" and c["action"] == "look_at" and c["args"].get("frame"),
        start,
    )
    setup.status(aim["id"], "done")
    pose = setup.probe.ask(op="measure")["pose"]
    forward = [pose[0][0], pose[1][0], pose[2][0]]
    target = [face[0] - pose[0][3], face[1] - pose[1][3], face[2] - HEAD_ORIGIN_Z_M - pose[2][3]]
    cosine = sum(f * t for f, t in zip(forward, target, strict=True)) / math.dist(target, (0, 0, 0))
    assert math.degrees(math.acos(min(1.0, cosine))) < 4.0, (
        setup.bridge_log.text(),
        forward,
        target,
        setup.commands.messages[start:],
        setup.feedback.messages[-10:],
    )
    setup.idle()


def test_the_robot_sleeps_with_the_sleep_activity_and_wakes_after(setup: Setup) -> None:
    start = setup.commands.mark()
    setup.request("start", "sleep")
    yawn = setup.command(lambda c: c["args"].get("name") == "sleep_pose", start)
    setup.status(yawn["id"], "done")
    asleep = setup.probe.ask(op="measure")
    # the SDK's sleep pose: antennas folded back (about 3 rad), head bowed
    assert asleep["left"] > 2.5 and asleep["right"] < -2.5, asleep
    # a bridge started while the robot sleeps leaves it asleep (its joints flowing)
    with token_deleted(setup.session, "robots/mini/alive/robot/feedback", timeout=WAIT_S):
        setup.stop_bridge()
    setup.bridge, setup.bridge_log = start_bridge(setup.daemon_port, setup.sim.port)
    wait_token(setup.session, "robots/mini/alive/robot/feedback", timeout=WAIT_S)
    mark = setup.joints.mark()
    setup.joints.wait_count(mark + 10, timeout=WAIT_S)  # a second of its control loop
    still = setup.probe.ask(op="measure")
    assert still["left"] > 2.5 and still["right"] < -2.5, still
    mark = setup.bridge_log.mark()
    setup.idle()
    setup.bridge_log.wait_for("awake (wake_up)", start=mark, timeout=WAIT_S)
    awake = setup.probe.ask(op="measure")
    assert abs(awake["left"]) < 0.5 and abs(awake["right"]) < 0.5, awake
    assert abs(awake["pitch"]) < 0.15, awake


def dashboard(sim: Simulator, path: str) -> Any:
    """A POST to the robot's daemon's REST API, as its dashboard's buttons do."""
    url = f"http://127.0.0.1:{sim.port}/api/apps/{path}"
    with urllib.request.urlopen(urllib.request.Request(url, method="POST"), timeout=30) as r:
        return json.loads(r.read() or b"null")


def test_the_robot_s_dashboard_starts_and_stops_dms_as_an_app(setup: Setup) -> None:
    """The installed bridge is listed as the app ``dms``; started from the dashboard it
    carries a robot's commands (``DMS_ROBOT`` from the daemon's environment)."""
    url = f"http://127.0.0.1:{setup.sim.port}/api/apps/list-available/installed"
    with urllib.request.urlopen(url, timeout=30) as listing:
        assert "dms" in [app["name"] for app in json.loads(listing.read())]
    alive = f"robots/{APP_ROBOT}/alive/robot/feedback"
    mark = setup.sim.log.mark()
    dashboard(setup.sim, "start-app/dms")
    try:
        wait_token(setup.session, alive, timeout=WAIT_S)
    except AssertionError:
        raise AssertionError("\n".join(setup.sim.log.lines[mark:])) from None
    feedback = Collector(setup.session, f"robots/{APP_ROBOT}/robot/feedback")
    command = {"id": "app-1", "channel": "motion", "action": "gesture", "args": {"name": "nod"}}
    put(setup.session, "robot/command", command, robot=APP_ROBOT)
    feedback.wait_for(lambda f: f["id"] == "app-1" and f["status"] == "done", timeout=30)
    with token_deleted(setup.session, alive, timeout=WAIT_S):
        dashboard(setup.sim, "stop-current-app")


HAND_RAD = 0.03
"""How close the recorded keyframe is to the pose the hand left (the simulator's head
settles within a hundredth of a radian; robot/joints is read ten times a second)."""


def test_the_studio_records_the_pose_a_hand_gave_the_robot(setup: Setup, tmp_path: Path) -> None:
    """Take the robot's pose: compensation on, the head moved "by hand" (the probe sends
    it through the SDK, which only a limp head would let it), Record takes robot/joints;
    off again, the bridge drives the head once more."""
    connect = ("--connect", f"tcp/127.0.0.1:{setup.daemon_port}")
    with running_studio(shipped_copy(tmp_path), connect) as studio:
        assert studio.request("GET", "/api/robot/by-hand") == (
            200,
            {"by_hand": False, "lease_s": 0.0, "renew_s": pytest.approx(10 / 3)},
        )
        status, on = studio.request("POST", "/api/robot/by-hand", {"on": True})
        assert status == 200 and on["by_hand"] is True and on["lease_s"] > 5, on
        setup.bridge_log.wait_for("gravity compensation on", timeout=WAIT_S)
        # the daemon's motion is refused while a hand poses the head
        pose = {"id": "pose-hand", "channel": "motion", "action": "pose"}
        pose["args"] = {"joints": {"hip": 0.0, "neck": 0.0, "head": 0.0}}
        put(setup.session, "robot/command", pose)
        assert "by hand" in setup.status("pose-hand", "failed")["detail"]
        hand = {"body_yaw": 0.3, "yaw": 0.75, "pitch": 0.2}
        setup.probe.ask(op="move", **hand)
        want = {"hip": 0.3, "neck": 0.45, "head": 0.2}
        setup.joints.wait_for(
            lambda j: all(abs(j["positions"][k] - v) < HAND_RAD for k, v in want.items()),
            start=setup.joints.mark(),
            timeout=WAIT_S,
        )
        status, recorded = studio.request("GET", "/api/robot?on=daemon")
        assert status == 200, recorded
        measured = setup.probe.ask(op="measure")
        held = {
            "hip": measured["body_yaw"],
            "neck": measured["yaw"] - measured["body_yaw"],
            "head": measured["pitch"],
        }
        assert set(recorded["joints"]) == set(want), recorded
        for joint, angle in held.items():
            assert abs(recorded["joints"][joint] - angle) < HAND_RAD, (recorded, measured)
        mark = setup.bridge_log.mark()
        status, off = studio.request("POST", "/api/robot/by-hand", {"on": False})
        assert (status, off["by_hand"]) == (200, False), off
        setup.bridge_log.wait_for("gravity compensation off", start=mark, timeout=WAIT_S)
        assert studio.request("GET", "/api/robot/by-hand")[1]["by_hand"] is False
        status, bad = studio.request("POST", "/api/robot/by-hand", {"on": "yes"})
        assert status == 400 and "on: true or false" in bad["error"], bad
    # compensation off: the daemon's motion is carried out again, from where the hand left it
    pose["id"] = "pose-after"
    put(setup.session, "robot/command", pose)
    setup.status("pose-after", "done", timeout=WAIT_S)
    after = setup.probe.ask(op="measure")
    assert abs(after["body_yaw"]) < 0.05 and abs(after["yaw"]) < 0.05, after


def test_a_lease_not_renewed_ends_by_hand_and_a_bad_ask_is_refused(setup: Setup) -> None:
    """A studio gone without asking off (a closed tab) leaves the robot limp no longer
    than its lease; an ask the bridge cannot read gets the reason back."""
    mark = setup.bridge_log.mark()
    [(ok, on)] = query(setup.session, "reachy/by_hand", {"on": True, "lease_s": 1})
    assert ok and on["by_hand"] is True, on
    setup.bridge_log.wait_for("gravity compensation on", start=mark, timeout=WAIT_S)
    setup.bridge_log.wait_for("gravity compensation off", start=mark, timeout=WAIT_S)
    assert query(setup.session, "reachy/by_hand") == [(True, {"by_hand": False, "lease_s": 0.0})]
    [(ok, refused)] = query(setup.session, "reachy/by_hand", {"on": True, "lease_s": 600})
    assert not ok and "lease_s" in refused["error"], refused
    [(ok, refused)] = query(setup.session, "reachy/by_hand", b"[]")
    assert not ok and "not a JSON object" in refused["error"], refused


@pytest.mark.skipif(browser_missing() is not None, reason=str(browser_missing()))
def test_the_studio_page_s_box_poses_the_robot_and_record_takes_its_joints(
    setup: Setup, tmp_path: Path
) -> None:
    """The page as a designer uses it, in Debian's Chromium: the box is offered (the
    robot is a Reachy Mini), ticked it turns compensation on, Record shows the joints
    the hand left, unticked it turns compensation off."""
    from playwright.sync_api import expect, sync_playwright

    connect = ("--connect", f"tcp/127.0.0.1:{setup.daemon_port}")
    with (
        running_studio(shipped_copy(tmp_path), connect) as studio,
        sync_playwright() as playwright,
    ):
        browser = playwright.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
        try:
            page = browser.new_page()
            page.goto(studio.url)
            box = page.locator("#by-hand")
            expect(box).to_be_enabled(timeout=WAIT_S * 1000)
            mark = setup.bridge_log.mark()
            box.check()
            setup.bridge_log.wait_for("gravity compensation on", start=mark, timeout=WAIT_S)
            expect(page.locator("#status")).to_contain_text("by hand")
            expect(page.locator("#try-on")).to_have_value("daemon")
            setup.probe.ask(op="move", body_yaw=-0.2, yaw=-0.5, pitch=-0.15)
            want = {"hip": -0.2, "neck": -0.3, "head": -0.15}
            setup.joints.wait_for(
                lambda j: all(abs(j["positions"][k] - v) < HAND_RAD for k, v in want.items()),
                start=setup.joints.mark(),
                timeout=WAIT_S,
            )
            page.locator("#record-button").click()
            status = page.locator("#status")
            expect(status).to_contain_text("recorded pose:")
            shown = dict(re.findall(r"(hip|neck|head) (-?\d+\.\d+)", status.inner_text()))
            assert set(shown) == set(want), shown
            for joint, angle in want.items():
                assert abs(float(shown[joint]) - angle) < HAND_RAD + 0.005, shown
            mark = setup.bridge_log.mark()
            box.uncheck()
            setup.bridge_log.wait_for("gravity compensation off", start=mark, timeout=WAIT_S)
            expect(status).to_contain_text("holds its pose")
        finally:
            browser.close()


def test_with_faces_a_robot_without_a_camera_publishes_nobody_in_front(setup: Setup) -> None:
    """``--faces`` asks the robot's daemon to track faces and publishes what it finds as
    ``perception/user``: the simulator has no camera (its daemon says so), so nobody is
    ever in front. (A face found is the pure mapping's, tested in tests/reachy/.)"""
    users = Collector(setup.session, "robots/faces/perception/user")
    mark = setup.sim.log.mark()
    argv = [sys.executable, "-m", "dms.cli", "reachy", "--robot", "faces", "--faces"]
    argv += ["--connect", f"tcp/127.0.0.1:{setup.daemon_port}"]
    argv += ["--host", "127.0.0.1", "--port", str(setup.sim.port)]
    bridge = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    log = StderrLines(bridge)
    try:
        setup.sim.log.wait_for("no camera available", start=mark, timeout=WAIT_S)
        users.wait_count(5, timeout=WAIT_S)
        assert all(UserPerception.model_validate(u).present is False for u in users.messages)
        assert users.messages[0] == {"present": False}
    finally:
        bridge.terminate()
        bridge.wait(20)
    assert bridge.returncode == 0, log.lines


def test_reachy_gone_is_reported_and_the_bridge_reconnects_when_it_returns(setup: Setup) -> None:
    with token_deleted(setup.session, "robots/mini/alive/robot/feedback", timeout=WAIT_S):
        setup.sim.kill()
    setup.bridge_log.wait_for("lost", timeout=WAIT_S)
    # a command while Reachy is away: unanswered, the activity is told it failed, and the
    # daemon marks the robot offline and says so
    mark = setup.decisions.mark()
    setup.request("start", "jokes")
    failed = setup.decisions.wait_for(
        lambda d: d["action"] == "fail" and d["activity"] == "jokes", start=mark, timeout=WAIT_S
    )
    assert failed["reason"] == "activity_error", failed
    setup.states.wait_for(lambda s: s["robot_link"] == "offline", timeout=WAIT_S)
    setup.errors.wait_for(lambda e: e["key"] == "robot" and "offline" in e["error"], timeout=WAIT_S)
    # Reachy's daemon comes back: the bridge reaches it, the daemon takes the robot back
    mark = setup.bridge_log.mark()
    setup.sim.start()
    setup.bridge_log.wait_for("reached", start=mark, timeout=WAIT_S)
    wait_token(setup.session, "robots/mini/alive/robot/feedback", timeout=WAIT_S)
    setup.states.wait_for(lambda s: s["robot_link"] == "ok", start=setup.states.mark(), timeout=30)
    setup.errors.wait_for(lambda e: e["key"] == "robot" and "back online" in e["error"])
    setup.probe.close()  # its connection went with the old simulator
    setup.probe = Probe(setup.sim.python, setup.sim.port)
    start = setup.commands.mark()
    setup.request("start", "presentation")
    wave = setup.command(lambda c: c["args"].get("name") == "wave", start, timeout=WAIT_S)
    setup.status(wave["id"], "done")
