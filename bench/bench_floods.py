"""Benchmarks of the daemon under floods of valid requests; prints one JSON object.

- a ``reload_rules`` flood: 2,000 requests in 4 s from another process (the request cap
  raised so that all are admitted): the longest ``dms/state`` gap and how many reloads ran;
- SIGTERM under a 500/s request flood: time from the signal to the process's exit
  (target ≤ 2 s), over ``--trials`` daemons.

Both against a real daemon process over real Zenoh on 127.0.0.1.

Usage: ``.venv/bin/python bench/bench_floods.py [--trials N] [--quick]``
"""

from __future__ import annotations

import argparse
import itertools
import json
import signal
import statistics
import sys
import tempfile
import threading
import time
from datetime import datetime
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.integration.harness import (  # noqa: E402
    Collector,
    DaemonProcess,
    client_session,
    paced,
    put,
)

RELOAD = {"action": "reload_rules", "by": "bench"}
UNCAPPED = "[inputs.rate_cap_per_s]\nrequest = 100000.0\n"


def _t(state: dict[str, Any]) -> float:
    return datetime.fromisoformat(str(state["time"]).replace("Z", "+00:00")).timestamp()


def _longest_gap(states: list[dict[str, Any]]) -> float:
    times = [_t(s) for s in states]
    return max((b - a for a, b in itertools.pairwise(times)), default=0.0)


def _flood(session: Any, rate: float, seconds: float, stop: threading.Event) -> int:
    """Send ``reload_rules`` requests at ``rate`` for ``seconds`` (or until ``stop``)."""
    sent = 0
    for request in paced(itertools.repeat(RELOAD, int(rate * seconds)), rate, stop):
        put(session, "request", request)
        sent += 1
    return sent


def bench_reload_flood(seconds: float = 4.0) -> dict[str, Any]:
    with tempfile.TemporaryDirectory() as tmp:
        daemon = DaemonProcess(Path(tmp), extra_config=UNCAPPED)
        session = client_session(daemon.port)
        try:
            daemon.start(session)
            states = Collector(session, "robots/mini/dms/state")
            states.wait_count(2)
            mark = states.mark()
            sent = _flood(session, 500.0, seconds, threading.Event())
            last = states.wait_for(lambda s: s["reloads"] >= 1, start=mark, timeout=20)
            states.wait_for(lambda s: _t(s) >= _t(last) + 2.0, start=mark, timeout=20)
            window = states.messages[mark:]
            return {
                "requests_sent": sent,
                "reloads_run": max(s["reloads"] for s in window),
                "longest_state_gap_s": round(_longest_gap(window), 3),
                "target_gap_s": 0.6,
            }
        finally:
            daemon.kill()
            session.close()


def bench_sigterm_under_flood(trials: int) -> dict[str, Any]:
    times: list[float] = []
    codes: list[int] = []
    for _ in range(trials):
        with tempfile.TemporaryDirectory() as tmp:
            daemon = DaemonProcess(Path(tmp), extra_config=UNCAPPED)
            session = client_session(daemon.port)
            stop = threading.Event()
            flooder = threading.Thread(target=_flood, args=(session, 500.0, 60.0, stop))
            try:
                daemon.start(session)
                flooder.start()
                time.sleep(2.0)  # the flood is under way (a bench, not a test)
                assert daemon.proc is not None
                t0 = time.monotonic()
                daemon.proc.send_signal(signal.SIGTERM)
                codes.append(daemon.proc.wait(30))
                times.append(time.monotonic() - t0)
            finally:
                stop.set()
                flooder.join(10)
                daemon.kill()
                session.close()
    return {
        "trials": trials,
        "exit_codes": sorted(set(codes)),
        "sigterm_to_exit_s_median": round(statistics.median(times), 3),
        "sigterm_to_exit_s_max": round(max(times), 3),
        "target_s": 2.0,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--trials", type=int, default=5)
    parser.add_argument(
        "--quick", action="store_true", help="a 1 s reload flood, one trial (smoke)"
    )
    args = parser.parse_args()
    print(
        json.dumps(
            {
                "reload_flood": bench_reload_flood(1.0 if args.quick else 4.0),
                "sigterm_under_flood": bench_sigterm_under_flood(1 if args.quick else args.trials),
            }
        )
    )


if __name__ == "__main__":
    main()
