"""A writer killed with SIGKILL at a random moment loses no acknowledged update."""

from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from memory import ProfileStore

ROUNDS = 20
ROOT = Path(__file__).resolve().parents[2]
HOST = Path(__file__).with_name("writer_host.py")


@pytest.mark.integration
def test_sigkill_loses_no_acknowledged_update(db_url: str) -> None:
    rng = random.Random(4)
    ProfileStore(db_url).close()  # create the schema once, before the writers race
    host = subprocess.Popen(
        [sys.executable, str(HOST), db_url],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
        cwd=ROOT,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
    )
    assert host.stdin is not None and host.stdout is not None
    results: list[tuple[str, int]] = []
    try:
        for round_ in range(ROUNDS):
            user = f"writer{round_}"
            host.stdin.write(f"go {user}\n")
            host.stdin.flush()
            kind, pid_text = host.stdout.readline().split()
            assert kind == "pid"
            pid = int(pid_text)
            kill_after = rng.randint(1, 40)
            acked = -1
            while acked + 1 < kill_after:
                line = host.stdout.readline().split()
                assert line[0] == "ack", line
                acked = int(line[1])
            os.kill(pid, signal.SIGKILL)
            while True:
                line = host.stdout.readline().split()
                if line[0] == "reaped":
                    assert line[1:] == [str(pid), str(int(signal.SIGKILL))]
                    break
                assert line[0] == "ack", line
                acked = int(line[1])
            results.append((user, acked))
    finally:
        host.stdin.close()
        host.wait(timeout=30)
    store = ProfileStore(db_url)
    try:
        for user, acked in results:
            data = store.export(user)
            counter = data["profile"]["attributes"]["counter"]
            # Every acknowledged update is there; at most one more, unacknowledged, may be.
            assert acked <= counter <= acked + 1, (user, acked, counter)
            scores = [entry["score"] for entry in data["feedback"]]
            assert len(scores) in (acked + 1, acked + 2), (user, acked, len(scores))
            assert scores[: acked + 1] == [(i % 101) / 100 for i in range(acked + 1)]
    finally:
        store.close()
