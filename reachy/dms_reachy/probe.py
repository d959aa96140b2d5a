"""``python -m dms_reachy.probe --host H --port P``: read a Reachy Mini from outside.

For the tests and the benchmark: a plain SDK client, driven by JSON lines on stdin
(``{"op": "measure"}``, ``{"op": "watch", "seconds": S}``, ``{"op": "move", "yaw": Y, ...}``
(a hand's stand-in: the head sent to those world angles), ``{"op": "quit"}``), answering
one JSON line each on stdout (a watch with ``"announce": true`` first says when it
began: ``{"watching": t}``). Times are ``time.monotonic()``, one clock for every process
of the machine. ``measure`` is the head pose (4x4), the body yaw and the
antennas; ``watch`` samples them at 50 Hz for ``S`` seconds and gives each axis's
extremes and when each first left its start by 0.02 rad.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from typing import Any

from dms_reachy.body import AXES, Posture
from dms_reachy.robot import Reachy, RobotGone

WATCH_PERIOD_S = 0.02
MOVED_RAD = 0.02


def measure(reachy: Reachy) -> dict[str, Any]:
    m = reachy.measure()
    pose = reachy.head_pose()
    return {
        "body_yaw": m.body_yaw,
        "yaw": m.yaw,
        "pitch": m.pitch,
        "roll": m.roll,
        "right": m.right,
        "left": m.left,
        "pose": [[float(v) for v in row] for row in pose],
        "t": time.monotonic(),
    }


def watch(reachy: Reachy, seconds: float) -> dict[str, Any]:
    axes = ("body_yaw", "yaw", "pitch", "roll", "right", "left")
    start = measure(reachy)
    low = {a: start[a] for a in axes}
    high = dict(low)
    moved: dict[str, float] = {}
    began = time.monotonic()
    deadline = began
    while time.monotonic() - began < seconds:
        now = measure(reachy)
        for a in axes:
            low[a], high[a] = min(low[a], now[a]), max(high[a], now[a])
            if a not in moved and abs(now[a] - start[a]) > MOVED_RAD:
                moved[a] = now["t"]
        deadline += WATCH_PERIOD_S
        time.sleep(max(0.0, deadline - time.monotonic()))
    return {"start": start, "low": low, "high": high, "moved": moved, "began": began}


def main() -> int:
    parser = argparse.ArgumentParser(prog="python -m dms_reachy.probe")
    parser.add_argument("--host", default="127.0.0.1")
    parser.add_argument("--port", type=int, required=True)
    args = parser.parse_args()
    reachy = Reachy(args.host, args.port, media=False)
    try:
        reachy.connect()
        print(json.dumps({"ready": True}), flush=True)
    except RobotGone as error:
        print(json.dumps({"error": str(error)}), flush=True)
    for line in sys.stdin:
        order = json.loads(line)
        try:
            if order["op"] == "quit":
                break
            if not reachy.connected:
                reachy.connect()
            if order["op"] == "measure":
                answer: dict[str, Any] = measure(reachy)
            elif order["op"] == "watch":
                if order.get("announce"):  # for a caller that moves the robot once watched
                    print(json.dumps({"watching": time.monotonic()}), flush=True)
                answer = watch(reachy, float(order["seconds"]))
            elif order["op"] == "move":
                reachy.send(Posture(**{a: float(order[a]) for a in AXES if a in order}))
                answer = {"sent": time.monotonic()}
            else:
                answer = {"error": f"unknown op {order['op']!r}"}
        except RobotGone as error:
            reachy.close()
            answer = {"error": str(error)}
        print(json.dumps(answer), flush=True)
    reachy.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
