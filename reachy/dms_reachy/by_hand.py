"""Posing Reachy Mini by hand: gravity compensation asked over Zenoh, for a lease.

The studio's "Take the robot's pose" asks on :data:`KEY` (a query, so that it learns
whether the daemon's robot is a Reachy Mini at all: nobody else answers there). While
the mode is on, the head's motors only carry its weight and the designer moves it; the
bridge sends no target and refuses motion (a target would fight the hand). Every ask
for ``on`` is a lease of ``lease_s`` seconds: a studio that goes away without asking
``off`` (a closed tab, a lost link) leaves the robot holding its pose again once the
lease runs out, never limp for good.

Payloads: ``{"on": true, "lease_s": 10}`` (on, or the lease renewed), ``{"on": false}``,
``{}`` (only the state). The reply: ``{"by_hand": bool, "lease_s": seconds left}``, or
an error reply ``{"error": "..."}`` naming what was wrong. Pure: :class:`Lease` takes
``now``.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass

KEY = "reachy/by_hand"
"""Relative to ``robots/<id>/``: the bridge's queryable."""
DEFAULT_LEASE_S = 10.0
LONGEST_LEASE_S = 120.0
MAX_PAYLOAD = 1024


class BadAsk(ValueError):
    """A request the bridge cannot read; the message says what was wrong."""


@dataclass(frozen=True, slots=True)
class Ask:
    """What a query asked: ``on`` None asks only the state."""

    on: bool | None
    lease_s: float = DEFAULT_LEASE_S


def parse(raw: bytes | None) -> Ask:
    """The ask in ``raw`` (empty: the state only); raises BadAsk naming the problem."""
    if not raw:
        return Ask(None)
    if len(raw) > MAX_PAYLOAD:
        raise BadAsk(f"{len(raw)} bytes, more than {MAX_PAYLOAD}")
    try:
        data = json.loads(raw)
    except (ValueError, UnicodeDecodeError):
        raise BadAsk('not JSON: {"on": true, "lease_s": 10} or {"on": false}') from None
    if not isinstance(data, dict):
        raise BadAsk('not a JSON object: {"on": true, "lease_s": 10} or {"on": false}')
    on = data.get("on")
    if on is not None and not isinstance(on, bool):
        raise BadAsk("on: true or false")
    lease = data.get("lease_s", DEFAULT_LEASE_S)
    if (
        isinstance(lease, bool)
        or not isinstance(lease, int | float)
        or not math.isfinite(lease)
        or not 0 < lease <= LONGEST_LEASE_S
    ):
        raise BadAsk(f"lease_s: seconds, more than 0 and at most {LONGEST_LEASE_S:g}")
    return Ask(on, float(lease))


class Lease:
    """Until when the robot is posed by hand (None: it is not)."""

    def __init__(self) -> None:
        self.until: float | None = None

    def take(self, ask: Ask, now: float) -> None:
        """Apply an ask at ``now``: on (re)starts the lease, off ends it."""
        if ask.on is True:
            self.until = now + ask.lease_s
        elif ask.on is False:
            self.until = None

    def wanted(self, now: float) -> bool:
        """True while the lease runs; an expired one is ended here."""
        if self.until is not None and now >= self.until:
            self.until = None
        return self.until is not None

    def left(self, now: float) -> float:
        return 0.0 if self.until is None else max(0.0, round(self.until - now, 3))
