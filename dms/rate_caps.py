"""Per-key rate caps: a flood of messages, queries or error reports stays cheap.

Each capped key has a token bucket (``rate`` a second, bursts up to ``burst``). The
daemon keeps two sets: one on what comes in (a message or a query over its key's cap is
dropped before it is even parsed), one on the ``dms/errors`` reports that rejected
messages cause (a flood of bad messages must not become a flood of reports and log
lines). What is dropped is counted in a :class:`DropTally`, summed per key and reported
once a second, never once per message: a flood costs a counter increment per message
and one report a second.

Called from Zenoh's threads: :meth:`RateCaps.admit` takes a lock held for a few
arithmetic operations. Pure of I/O and of the clock: callers pass monotonic seconds.
"""

from __future__ import annotations

import threading
from collections.abc import Mapping
from dataclasses import dataclass

REPORT_EVERY_S = 1.0
"""Drops are summed and reported at most this often."""


@dataclass(frozen=True, slots=True)
class Drops:
    """What was dropped on one key since its last report."""

    key: str
    count: int
    total: int
    """Since the start."""
    latest: str | None = None
    """What was dropped last, when the caller names it (one of a flood of distinct keys)."""


class DropTally:
    """Counts of things dropped per key, handed out at most once every
    :data:`REPORT_EVERY_S` (thread-safe): one report per interval, whatever the count."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._pending: dict[str, int] = {}
        self._totals: dict[str, int] = {}
        self._latest: dict[str, str] = {}
        self._reported = -REPORT_EVERY_S

    def add(self, key: str, count: int = 1, latest: str | None = None) -> None:
        """Count ``count`` dropped on ``key``; ``latest`` names the last of them."""
        with self._lock:
            self._pending[key] = self._pending.get(key, 0) + count
            self._totals[key] = self._totals.get(key, 0) + count
            if latest is not None:
                self._latest[key] = latest

    def total(self, key: str) -> int:
        """Dropped on ``key`` since the start."""
        with self._lock:
            return self._totals.get(key, 0)

    def due(self, monotonic: float) -> list[Drops]:
        """The drops since the last report, per key, unless one was made within the interval."""
        with self._lock:
            if not self._pending or monotonic - self._reported < REPORT_EVERY_S:
                return []
            due = [
                Drops(key, count, self._totals[key], self._latest.get(key))
                for key, count in self._pending.items()
            ]
            self._pending.clear()
            self._reported = monotonic
            return due


@dataclass(slots=True)
class _Bucket:
    rate: float
    burst: float
    tokens: float
    refilled: float | None = None


class RateCaps:
    """Token buckets per key; keys without a cap are always admitted.

    ``label`` and ``noun`` name what is capped in the report lines
    (``rate cap 50/s: dropped 120 messages (840 since start)``).
    """

    def __init__(
        self,
        caps: Mapping[str, float],
        burst_s: float = 1.0,
        label: str = "rate cap",
        noun: str = "messages",
    ) -> None:
        """``caps``: admitted a second per key; ``burst_s``: seconds of rate a burst may use."""
        self._lock = threading.Lock()
        self._buckets = {
            key: _Bucket(rate, max(1.0, rate * burst_s), max(1.0, rate * burst_s))
            for key, rate in caps.items()
        }
        self._label = label
        self._noun = noun
        self.drops = DropTally()

    def cap(self, key: str) -> float | None:
        """The rate of ``key``'s cap (None: uncapped)."""
        bucket = self._buckets.get(key)
        return bucket.rate if bucket is not None else None

    def admit(self, key: str, monotonic: float) -> bool:
        """True if one more on ``key`` at ``monotonic`` is under its cap; else it is counted."""
        bucket = self._buckets.get(key)
        if bucket is None:
            return True
        with self._lock:
            if bucket.refilled is None:
                bucket.refilled = monotonic
            elapsed = monotonic - bucket.refilled
            if elapsed > 0:
                bucket.tokens = min(bucket.burst, bucket.tokens + elapsed * bucket.rate)
                bucket.refilled = monotonic
            if bucket.tokens >= 1.0:
                bucket.tokens -= 1.0
                return True
        self.drops.add(key)
        return False

    def due_reports(self, monotonic: float) -> list[tuple[str, str]]:
        """At most once every :data:`REPORT_EVERY_S`: ``(key, line)`` per key that dropped."""
        return [
            (
                drops.key,
                f"{self._label} {self._buckets[drops.key].rate:g}/s: dropped {drops.count}"
                f" {self._noun} ({drops.total} since start)",
            )
            for drops in self.drops.due(monotonic)
        ]

    def dropped(self, key: str) -> int:
        """Dropped on ``key`` since the start."""
        return self.drops.total(key)
