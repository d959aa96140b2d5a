"""What the hostile-peer and flood tests share: reports on ``dms/errors`` with waits
that look only at new ones, sentinels that prove a key's earlier messages were read,
paced floods, and the ``dms/state`` timing they measure.

State gaps are measured on the ``time`` field of consecutive ``dms/state`` messages (the
daemon's own clock).
"""

from __future__ import annotations

import itertools
import json
import re
import threading
import time
from collections import Counter
from collections.abc import Callable, Iterable
from datetime import datetime
from typing import Any

import zenoh

from dms.kernel.keys import INPUT_KEYS
from tests.integration.harness import Collector, paced, put, wait_token

MAX_STATE_GAP_S = 0.6
ALIVE = "robots/mini/alive/dms"


def caps(rate: float, keys: Iterable[str] = INPUT_KEYS) -> str:
    """TOML raising the rate caps (a sub-table: the harness's config has ``[inputs]``)."""
    return "[inputs.rate_cap_per_s]\n" + "".join(f'"{key}" = {rate}\n' for key in keys)


def ts(message: dict[str, Any]) -> float:
    return datetime.fromisoformat(message["time"].replace("Z", "+00:00")).timestamp()


def longest_gap(states: list[dict[str, Any]]) -> float:
    times = [ts(s) for s in states]
    return max((b - a for a, b in itertools.pairwise(times)), default=0.0)


class Reports:
    """Every ``dms/errors`` report, with waits that look only at the new ones (a fuzz
    brings thousands; :class:`Collector` rescans them all on each)."""

    def __init__(self, session: zenoh.Session) -> None:
        self.messages: list[dict[str, Any]] = []
        self._cond = threading.Condition()
        self._sub = session.declare_subscriber("robots/mini/dms/errors", self._on)

    def _on(self, sample: zenoh.Sample) -> None:
        message = json.loads(sample.payload.to_bytes())
        with self._cond:
            self.messages.append(message)
            self._cond.notify_all()

    def wait_for(
        self, predicate: Callable[[dict[str, Any]], bool], timeout: float = 20.0, start: int = 0
    ) -> tuple[int, dict[str, Any]]:
        """The index and the first report from ``start`` on that satisfies ``predicate``."""
        seen = start
        deadline = time.monotonic() + timeout
        with self._cond:
            while True:
                while seen < len(self.messages):
                    if predicate(self.messages[seen]):
                        return seen, self.messages[seen]
                    seen += 1
                left = deadline - time.monotonic()
                if left <= 0:
                    raise AssertionError(
                        f"no matching report within {timeout}s; last: {self.messages[-5:]}"
                    )
                self._cond.wait(left)

    def on(self, key: str, start: int = 0, end: int | None = None) -> list[dict[str, Any]]:
        with self._cond:
            return [r for r in self.messages[start:end] if r["key"] == key]

    def mark(self) -> int:
        with self._cond:
            return len(self.messages)

    def all(self) -> list[dict[str, Any]]:
        with self._cond:
            return list(self.messages)


SENTINELS = itertools.count(1000)
SENTINELS_SENT: Counter[str] = Counter()


def sentinel(
    session: zenoh.Session, reports: Reports, key: str, start: int = 0, timeout: float = 30.0
) -> int:
    """Put on ``key`` a payload the daemon must reject with a report that names a fresh
    number (a newline count: "line N"), and wait for that report; every message put on
    ``key`` before it has then been read (Zenoh runs each subscriber's callback in the
    order its samples came; different keys' callbacks interleave). The report's index."""
    lines = next(SENTINELS)
    SENTINELS_SENT[key] += 1
    put(session, key, b"\n" * lines + b"!")
    index, _ = reports.wait_for(
        lambda r: r["key"] == key and f"line {lines + 1} column 1 " in r["error"],
        timeout=timeout,
        start=start,
    )
    return index


def is_sentinel(report: dict[str, Any]) -> bool:
    return (
        re.fullmatch(r"not JSON: Expecting value: line \d+ column 1 \(char \d+\)", report["error"])
        is not None
    )


def assert_alive(daemon: Any, session: zenoh.Session, states: Collector) -> None:
    assert daemon.proc.poll() is None, daemon.log.read_text()[-3000:]
    wait_token(session, ALIVE, timeout=10)
    mark = states.mark()
    states.wait_count(mark + 2, timeout=10)  # dms/state keeps coming


def flood(
    session: zenoh.Session,
    key: str,
    payloads: Iterable[dict[str, Any]],
    rate: float,
    stop: threading.Event | None = None,
    sent: list[int] | None = None,
) -> None:
    """Put ``payloads`` on ``key`` at ``rate`` a second until they run out or ``stop``."""
    for index, payload in enumerate(paced(payloads, rate, stop)):
        put(session, key, payload)
        if sent is not None:
            sent[0] = index + 1


def state_after(states: Collector, wall: float, timeout: float = 20.0) -> dict[str, Any]:
    """The first ``dms/state`` stamped at or after ``wall`` (UTC seconds, the daemon's clock)."""
    return states.wait_for(lambda s: ts(s) >= wall, timeout=timeout)
