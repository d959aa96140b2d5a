"""A ``robot/command`` to the start of the simulated Reachy Mini's motion through ``dms
reachy``, and the bridge's memory and CPU; prints one JSON object.

The maker's MuJoCo simulator runs on a loopback port (``dms_reachy.simulator``); the
bridge runs as ``dms reachy`` runs it, connected to this process's Zenoh session (a peer
listening on 127.0.0.1), which plays the daemon: it publishes ``aim`` ``turn_to``
commands, the head turning 0.3 rad left, then right, one at a time. A plain SDK client
(``dms_reachy.probe``) samples the head at 50 Hz; a command's latency is from its
publication to the first sample whose head yaw left its place by 0.02 rad (both stamps on
the machine's one monotonic clock).

- ``command_to_motion_ms``: p50, p95 and max of that latency, in milliseconds (the
  sampling adds up to 20 ms, the bridge's control period up to 20 ms);
- ``bridge_rss_mb``: the bridge's resident memory after the commands;
- ``bridge_cpu_percent_idle`` / ``_moving``: its CPU use (one core = 100) while it holds
  the robot still for 5 s (``--quick``: 2 s), and over the commands.

Run: ``.venv/bin/python bench/bench_reachy.py [--commands 100]`` (``--quick``: 10). The
bridge's environment must exist (``dms reachy --prepare``; CI makes it).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import zenoh  # noqa: E402

from dms.reachy_cli import prepare  # noqa: E402
from tests.integration.harness import free_port, wait_token  # noqa: E402
from tests.integration.test_reachy import Probe, Simulator  # noqa: E402

TURN_RAD = 0.3
WATCH_S = 1.0
TICKS_PER_S = os.sysconf("SC_CLK_TCK")


def listening_session(port: int) -> zenoh.Session:
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("listen/endpoints", json.dumps([f"tcp/127.0.0.1:{port}"]))
    conf.insert_json5("scouting/multicast/enabled", "false")
    return zenoh.open(conf)


def cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICKS_PER_S


def rss_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return round(int(line.split()[1]) / 1024, 1)
    return 0.0


def percentile(values: list[float], share: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(len(ordered) * share))]


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--commands", type=int, default=100)
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args()
    commands = 10 if args.quick else args.commands
    idle_s = 2.0 if args.quick else 5.0
    python = prepare(echo=False)
    sim = Simulator(python, free_port())
    port = free_port()
    session = listening_session(port)
    bridge: subprocess.Popen[str] | None = None
    probe: Probe | None = None
    try:
        sim.start()
        argv = [sys.executable, "-m", "dms.cli", "reachy", "--connect", f"tcp/127.0.0.1:{port}"]
        argv += ["--host", "127.0.0.1", "--port", str(sim.port)]
        bridge = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        wait_token(session, "robots/mini/alive/robot/feedback")
        probe = Probe(python, sim.port)
        done = threading.Event()

        def on_feedback(sample: zenoh.Sample) -> None:
            if json.loads(sample.payload.to_bytes())["status"] == "done":
                done.set()

        feedback = session.declare_subscriber("robots/mini/robot/feedback", on_feedback)
        idle_cpu = cpu_seconds(bridge.pid)
        idle_start = time.monotonic()
        threading.Event().wait(idle_s)  # a measured stretch of idling, not a wait for a peer
        idle_percent = 100 * (cpu_seconds(bridge.pid) - idle_cpu) / (time.monotonic() - idle_start)
        latencies: list[float] = []
        moving_cpu, moving_start = cpu_seconds(bridge.pid), time.monotonic()
        for index in range(commands):
            neck = TURN_RAD if index % 2 == 0 else -TURN_RAD
            command = {
                "id": f"bench-{index}",
                "channel": "aim",
                "action": "turn_to",
                "args": {"joints": {"neck": neck}, "frame": None},
            }
            probe.watch_announced(WATCH_S)
            done.clear()
            sent = time.monotonic()
            session.put("robots/mini/robot/command", json.dumps(command).encode())
            seen = probe.result()
            if "yaw" in seen["moved"]:
                latencies.append(seen["moved"]["yaw"] - sent)
            done.wait(10.0)
        moving_percent = (
            100 * (cpu_seconds(bridge.pid) - moving_cpu) / (time.monotonic() - moving_start)
        )
        feedback.undeclare()
        ms = [v * 1000 for v in latencies]
        print(
            json.dumps(
                {
                    "benchmark": "reachy",
                    "commands": commands,
                    "moved": len(latencies),
                    "command_to_motion_ms": {
                        "p50": round(statistics.median(ms), 1) if ms else None,
                        "p95": round(percentile(ms, 0.95), 1) if ms else None,
                        "max": round(max(ms), 1) if ms else None,
                    },
                    "bridge_rss_mb": rss_mb(bridge.pid),
                    "bridge_cpu_percent_idle": round(idle_percent, 1),
                    "bridge_cpu_percent_moving": round(moving_percent, 1),
                }
            )
        )
    finally:
        if probe is not None:
            probe.close()
        if bridge is not None and bridge.poll() is None:
            bridge.terminate()
            bridge.wait(20)
        sim.kill()
        session.close()


if __name__ == "__main__":
    main()
