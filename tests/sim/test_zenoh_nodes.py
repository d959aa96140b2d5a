"""The demo visitor and the simulated robot as real Zenoh participants beside a daemon.

The daemon runs as a subprocess on a free loopback port with multicast scouting off;
every wait is for a message or a token, with a deadline.
"""

from __future__ import annotations

import subprocess
import sys
import threading
from pathlib import Path

import pytest
import zenoh

from dms.bus import ZenohClient, make_config
from dms.config import Settings
from dms.kernel.clock import RealClock
from sim.robot_node import RobotNode
from sim.visitor import start_visitor
from tests.integration.harness import (
    Collector,
    DaemonProcess,
    client_session,
    put,
    running_daemon,
    wait_token,
)

pytestmark = pytest.mark.integration


def test_demo_visitor_makes_a_session_within_ten_seconds(tmp_path: Path) -> None:
    with running_daemon(tmp_path) as (daemon, session):
        decisions = Collector(session, "robots/mini/dms/decision")
        perception = Collector(session, "robots/mini/perception/**")
        settings = Settings.model_validate(
            {"zenoh": {"listen": [f"tcp/127.0.0.1:{daemon.port}"]}, "seed": 1}
        )
        stop = start_visitor("demo", settings)
        try:
            wait_token(session, "robots/mini/alive/perception/user", timeout=10.0)
            first = decisions.wait_for(
                lambda d: d["action"] == "start" and d["chosen_by"] in ("user", "robot"),
                timeout=10.0,
            )
            assert first["activity"] is not None
            # The visitor answers what the robot asks, by voice or on the screen.
            perception.wait_for(lambda m: "text" in m or "choice" in m, timeout=15.0)
            gone = threading.Event()

            def on_token(sample: zenoh.Sample) -> None:
                if sample.kind == zenoh.SampleKind.DELETE:
                    gone.set()

            watcher = session.liveliness().declare_subscriber(
                "robots/mini/alive/perception/user", on_token
            )
        finally:
            stop()
        assert gone.wait(10.0), "the visitor's perception token stayed after stop()"
        watcher.undeclare()  # type: ignore[no-untyped-call]
        assert daemon.terminate() == 0


def test_sim_robot_answers_commands_over_zenoh(tmp_path: Path) -> None:
    daemon = DaemonProcess(tmp_path)
    session = client_session(daemon.port)
    robot_client = ZenohClient("mini", make_config(connect=[f"tcp/127.0.0.1:{daemon.port}"]))
    node = RobotNode(robot_client, RealClock(), seed=2)
    thread = threading.Thread(target=node.run, daemon=True)
    proc = None
    try:
        feedback = Collector(session, "robots/mini/robot/feedback")
        commands = Collector(session, "robots/mini/robot/command")
        proc = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "dms.cli",
                "run",
                "--config",
                str(daemon.config),
                "--db",
                daemon.db,
                "--listen",
                f"tcp/127.0.0.1:{daemon.port}",
                "--robot",
                "zenoh",
            ],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        wait_token(session, "robots/mini/alive/dms")
        thread.start()
        wait_token(session, "robots/mini/alive/robot/feedback", timeout=10.0)
        mark = commands.mark()  # a command sent before the robot listened gets no answer
        put(session, "perception/user", {"present": True, "user_id": "alice", "ready": True})
        put(session, "request", {"action": "start", "activity": "jokes", "by": "test"})
        command = commands.wait_for(lambda c: c["action"] != "interrupt", timeout=10.0, start=mark)
        done = feedback.wait_for(
            lambda f: f["id"] == command["id"] and f["status"] in ("done", "interrupted"),
            timeout=30.0,
        )
        assert done["status"] in ("done", "interrupted")
        assert node.commands >= 1 and node.feedback >= 2
    finally:
        node.stopped.set()
        if thread.is_alive():
            thread.join(5.0)
        robot_client.close()
        if proc is not None:
            proc.terminate()
            proc.wait(20)
        session.close()  # type: ignore[no-untyped-call]
