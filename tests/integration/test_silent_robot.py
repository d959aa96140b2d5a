"""An external robot that stops answering, over real Zenoh beside a real daemon.

The daemon runs with ``--robot zenoh`` and no robot at first: its commands go
unacknowledged, it marks the robot offline in ``dms/state`` and stops starting
activities (rare probes aside). When a robot process declares ``alive/robot/feedback``
and answers, the link is ``ok`` again at once and the activities go on.
"""

from __future__ import annotations

import itertools
import threading
from datetime import datetime
from pathlib import Path

import pytest

from dms.bus import ZenohClient, make_config
from dms.kernel.clock import RealClock
from sim.robot_node import RobotNode
from tests.integration.harness import Collector, DaemonProcess, client_session, put, wait_token

pytestmark = pytest.mark.integration

SILENT = "ack_timeout_s = 1.0\noffline_after_unacked = 2\noffline_retry_max_s = 30.0\n"


def _t(message: dict[str, object]) -> float:
    return datetime.fromisoformat(str(message["time"]).replace("Z", "+00:00")).timestamp()


def test_a_silent_robot_is_marked_offline_and_welcomed_back(tmp_path: Path) -> None:
    daemon = DaemonProcess(tmp_path, extra_config=SILENT, extra_args=("--robot", "zenoh"))
    session = client_session(daemon.port)
    robot_client: ZenohClient | None = None
    node: RobotNode | None = None
    thread: threading.Thread | None = None
    try:
        states = Collector(session, "robots/mini/dms/state")
        decisions = Collector(session, "robots/mini/dms/decision")
        errors = Collector(session, "robots/mini/dms/errors")
        daemon.start(session)
        put(session, "perception/user", {"present": True, "user_id": "ann", "ready": True})
        offline = states.wait_for(lambda s: s["robot_link"] == "offline", timeout=30)
        errors.wait_for(lambda e: e["key"] == "robot" and "offline" in e["error"])

        # offline: in the next 12 s only probes, 1 s, 2 s, 4 s... apart (a start every
        # second or so without the backoff: the menu times out after 1 s, then again)
        mark = decisions.mark()
        states.wait_for(lambda s: _t(s) >= _t(offline) + 12.0, timeout=40)
        starts = [_t(d) for d in decisions.messages[mark:] if d["action"] == "start"]
        assert len(starts) <= 3, starts
        gaps = [b - a for a, b in itertools.pairwise(starts)]
        assert gaps == sorted(gaps), gaps
        # an app's request is answered, not dropped
        put(session, "request", {"action": "start", "activity": "quiz", "by": "app"})
        decisions.wait_for(
            lambda d: d["activity"] == "quiz" and d["detail"] == "the robot is offline",
            start=mark,
        )

        # the robot comes: its token, then its answers
        robot_client = ZenohClient("mini", make_config(connect=[f"tcp/127.0.0.1:{daemon.port}"]))
        node = RobotNode(robot_client, RealClock(), seed=2)
        thread = threading.Thread(target=node.run, daemon=True)
        thread.start()
        wait_token(session, "robots/mini/alive/robot/feedback", timeout=20)
        back = states.wait_for(lambda s: s["robot_link"] == "ok", start=states.mark() - 1)
        mark = decisions.mark()
        put(session, "request", {"action": "start", "activity": "jokes", "by": "app"})
        decisions.wait_for(
            lambda d: d["action"] == "start" and d["activity"] == "jokes", start=mark, timeout=15
        )
        assert _t(back) - _t(offline) > 0
        errors.wait_for(lambda e: e["key"] == "robot" and "back online" in e["error"])
        assert daemon.terminate() == 0
    finally:
        if node is not None:
            node.stopped.set()
        if thread is not None and thread.is_alive():
            thread.join(5.0)
        if robot_client is not None:
            robot_client.close()
        daemon.kill()
        session.close()
