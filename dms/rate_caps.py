"""Per-key rate caps on the daemon's inputs: a flood of valid messages stays cheap.

Each input key has a token bucket (``rate`` messages a second, bursts up to
``burst``). A message over the cap is dropped before it is even parsed, and counted;
the drops are summed per key and reported once a second, never once per message, so a
flood costs the daemon a counter increment per message and one report a second.

Called from Zenoh's threads: :meth:`RateCaps.admit` takes a lock held for a few
arithmetic operations. Pure of I/O and of the clock: callers pass monotonic seconds.
"""

from __future__ import annotations

import threading
from collections.abc import Mapping
from dataclasses import dataclass

REPORT_EVERY_S = 1.0


@dataclass(slots=True)
class _Bucket:
    rate: float
    burst: float
    tokens: float
    refilled: float | None = None
    dropped: int = 0
    dropped_total: int = 0


class RateCaps:
    """Token buckets per input key; keys without a cap are always admitted."""

    def __init__(self, caps: Mapping[str, float], burst_s: float = 1.0) -> None:
        """``caps``: messages a second per key; ``burst_s``: seconds of rate a burst may use."""
        self._lock = threading.Lock()
        self._buckets = {
            key: _Bucket(rate, max(1.0, rate * burst_s), max(1.0, rate * burst_s))
            for key, rate in caps.items()
        }
        self._reported = -REPORT_EVERY_S

    def admit(self, key: str, monotonic: float) -> bool:
        """True if a message on ``key`` arriving at ``monotonic`` is under its cap."""
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
            bucket.dropped += 1
            bucket.dropped_total += 1
            return False

    def due_reports(self, monotonic: float) -> list[tuple[str, str]]:
        """At most once every :data:`REPORT_EVERY_S`: ``(key, line)`` per key that dropped."""
        with self._lock:
            if monotonic - self._reported < REPORT_EVERY_S:
                return []
            reports = []
            for key, bucket in self._buckets.items():
                if bucket.dropped:
                    reports.append(
                        (
                            key,
                            f"rate cap {bucket.rate:g}/s: dropped {bucket.dropped} messages"
                            f" ({bucket.dropped_total} since start)",
                        )
                    )
                    bucket.dropped = 0
            if reports:
                self._reported = monotonic
            return reports

    def dropped(self, key: str) -> int:
        """Messages on ``key`` dropped since the start."""
        bucket = self._buckets.get(key)
        return bucket.dropped_total if bucket is not None else 0
