"""A request from a ROS 2 node to its decision back, through ``dms ros2``, beside the
same round trip over Zenoh; prints one JSON object.

A daemon (the simulated Mini) listens on a loopback port; the bridge runs as ``dms
ros2`` runs it; a ROS 2 node (``dms_ros2.probe``) publishes ``request`` on
``/robots/mini/request`` and times the decision on ``/robots/mini/dms/decision`` (both
stamps taken in that node). The Zenoh rounds put the same requests on
``robots/mini/request`` from this process and time ``robots/mini/dms/decision``. The
requests alternate ``start jokes`` and ``cancel jokes``, so each has one decision to
wait for. Fast DDS keeps to loopback, as in the tests (``ros2/loopback_fastdds.xml``).

- ``ros2_ms`` / ``zenoh_ms``: p50, p99 and max of the round trip, in milliseconds.

Without the bridge's environment (it cannot be made) it prints ``{"skipped": reason}``.

Run: ``.venv/bin/python bench/bench_ros2.py [--rounds 200]`` (``--quick``: 20 rounds).
"""

from __future__ import annotations

import argparse
import json
import os
import queue
import statistics
import sys
import tempfile
import time
from functools import partial
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import zenoh  # noqa: E402

from dms.kernel.errors import ConfigError  # noqa: E402
from dms.ros2_cli import prepare  # noqa: E402
from tests.integration.harness import DaemonProcess, client_session, paced, put  # noqa: E402
from tests.integration.test_ros2 import BridgeProcess, Probe, ros_env  # noqa: E402

PACE_S = 0.05
"""A request every 50 ms at most: under the daemon's rate cap on ``request`` (50/s), over
which requests are dropped unanswered."""
REQUESTS = (
    ({"action": "start", "activity": "jokes", "by": "bench"}, "start"),
    ({"action": "cancel", "activity": "jokes", "by": "bench"}, "cancel"),
)


def summary(values_s: list[float]) -> dict[str, float]:
    ms = sorted(v * 1000 for v in values_s)
    p99 = ms[min(len(ms) - 1, int(len(ms) * 0.99))]
    return {
        "p50": round(statistics.median(ms), 2),
        "p99": round(p99, 2),
        "max": round(ms[-1], 2),
    }


def is_decision(event: dict[str, Any], action: str) -> bool:
    """Whether a probe's event is the decision ``action`` on jokes."""
    if event["event"] != "msg" or event["topic"] != "/robots/mini/dms/decision":
        return False
    decision = json.loads(event["msg"]["data"])
    return bool(decision["action"] == action and decision["activity"] == "jokes")


def ros2_rounds(probe: Probe, rounds: int) -> list[float]:
    out = []
    for index, _ in enumerate(paced(range(rounds), 1 / PACE_S)):
        request, action = REQUESTS[index % 2]
        mark = probe.mark()
        probe.pub("/robots/mini/request", {"data": json.dumps(request)})
        sent = probe.wait_for(lambda e: e["event"] == "published", start=mark, timeout=30)
        got = probe.wait_for(partial(is_decision, action=action), start=mark, timeout=30)
        out.append(got["t"] - sent["t"])
    return out


def zenoh_rounds(session: zenoh.Session, rounds: int) -> list[float]:
    arrived: queue.Queue[tuple[float, dict[str, Any]]] = queue.Queue()
    sub = session.declare_subscriber(
        "robots/mini/dms/decision",
        lambda s: arrived.put((time.monotonic(), json.loads(s.payload.to_bytes()))),
    )
    out = []
    try:
        for index, _ in enumerate(paced(range(rounds), 1 / PACE_S)):
            request, action = REQUESTS[index % 2]
            sent = time.monotonic()
            put(session, "request", request)
            while True:
                at, decision = arrived.get(timeout=30)
                if decision["action"] == action and decision["activity"] == "jokes":
                    break
            out.append(at - sent)
    finally:
        sub.undeclare()
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=200, help="round trips each way")
    parser.add_argument("--quick", action="store_true", help="20 rounds (smoke)")
    args = parser.parse_args()
    rounds = 20 if args.quick else args.rounds
    try:
        python = prepare(echo=False)
    except ConfigError as error:
        print(json.dumps({"skipped": str(error)}))
        return 0
    env = ros_env(domain=95 + os.getpid() % 7)  # apart from the tests' (10 to 90)
    started = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="dms-bench-ros2-") as folder:
        tmp = Path(folder)
        daemon = DaemonProcess(tmp)
        session = client_session(daemon.port)
        bridge: BridgeProcess | None = None
        probe: Probe | None = None
        try:
            daemon.start(session)
            bridge = BridgeProcess(daemon.port, env, tmp / "bridge.log")
            probe = Probe(python, env)
            probe.sub("/robots/mini/dms/decision")
            probe.sub("/robots/mini/dms/state", qos="latched")
            probe.message("/robots/mini/dms/state")  # the bridge is there
            ros2_rounds(probe, 2)  # discovery of the request topic, not timed
            ros2 = ros2_rounds(probe, rounds)
            over_zenoh = zenoh_rounds(session, rounds)
        finally:
            if probe is not None:
                probe.close()
            if bridge is not None:
                bridge.stop()
            daemon.kill()
            session.close()
    result = {
        "rounds": rounds,
        "ros2_ms": summary(ros2),
        "zenoh_ms": summary(over_zenoh),
        "wall_s": round(time.monotonic() - started, 1),
    }
    print(json.dumps(result, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
