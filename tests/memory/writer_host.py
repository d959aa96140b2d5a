"""A writer for the SIGKILL test: forks one writer per ``go USER`` line on stdin.

Forking from this already-imported process keeps each round fast. The child opens
its own store and loops: record a feedback, set ``counter``, then print
``ack N`` once both are committed. The host prints ``pid P`` before the child
starts writing and ``reaped P SIGNAL`` when the child is gone.
"""

from __future__ import annotations

import os
import sys
from datetime import UTC, datetime, timedelta

from memory.store import ProfileStore

START = datetime(2026, 11, 22, 10, 0, tzinfo=UTC)


def write_forever(url: str, user: str) -> None:
    store = ProfileStore(url)
    store.get_or_create(user, START)
    index = 0
    while True:
        now = START + timedelta(seconds=index)
        store.record_feedback(user, "quiz", (index % 101) / 100, now)
        store.update(user, now, counter=index)
        print(f"ack {index}", flush=True)
        index += 1


def main(url: str) -> None:
    for line in sys.stdin:
        command = line.split()
        if command[:1] != ["go"]:
            return
        ready_read, ready_write = os.pipe()
        sys.stdout.flush()
        pid = os.fork()
        if pid == 0:
            os.close(ready_write)
            os.read(ready_read, 1)  # wait until the host has announced our pid
            write_forever(url, command[1])
            os._exit(0)
        os.close(ready_read)
        print(f"pid {pid}", flush=True)
        os.write(ready_write, b"x")
        os.close(ready_write)
        _, status = os.waitpid(pid, 0)
        print(f"reaped {pid} {os.WTERMSIG(status) if os.WIFSIGNALED(status) else 0}", flush=True)


if __name__ == "__main__":
    main(sys.argv[1])
