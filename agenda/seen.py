"""Who this robot saw, and when: what decides whether it records a user's misses.

In a fleet a robot records the misses of the users it saw since the occurrence fell due
(:meth:`agenda.service.Agenda._saw`); the robot that next sees the user records the
rest. A sighting matters only while an occurrence that fell due before it can still be
missed, at most ``MAX_LEAD_S + MAX_GRACE_S`` after it; older ones are dropped, and
past :data:`MAX_SEEN_USERS` the least recently seen user is dropped first, so a flood of
distinct user ids never grows the daemon. Deliveries never depend on it.
"""

from __future__ import annotations

from collections import OrderedDict

from agenda.rows import MAX_GRACE_S, MAX_LEAD_S

US_PER_S = 1_000_000
SEEN_KEEP_S = MAX_LEAD_S + MAX_GRACE_S + 86400
"""How long a sighting is kept: past it every occurrence due before it is settled."""
MAX_SEEN_USERS = 10_000
"""Users kept at most: more distinct people than a robot meets in :data:`SEEN_KEEP_S`.
Past it, the robot that next sees a dropped user records their misses instead."""


class SeenUsers:
    """User id -> when this robot last saw them, least recently seen first.

    Not thread-safe: the agenda calls it with its index lock held.
    """

    def __init__(self, keep_s: int = SEEN_KEEP_S, bound: int = MAX_SEEN_USERS) -> None:
        self._at: OrderedDict[str, int] = OrderedDict()
        self._keep_us = keep_s * US_PER_S
        self._bound = bound

    def __len__(self) -> int:
        return len(self._at)

    def saw(self, user_id: str, at_us: int) -> None:
        """``user_id`` was seen at ``at_us`` (an earlier time never moves theirs back)."""
        before = self._at.get(user_id)
        if before is None:
            self._at[user_id] = at_us
            self._drop_old(at_us)
        else:
            self._at[user_id] = max(before, at_us)
            self._at.move_to_end(user_id)

    def last(self, user_id: str) -> int | None:
        """When ``user_id`` was last seen; None when never (or too long ago to matter)."""
        return self._at.get(user_id)

    def _drop_old(self, now_us: int) -> None:
        while len(self._at) > self._bound:
            self._at.popitem(last=False)
        horizon = now_us - self._keep_us
        while self._at and next(iter(self._at.values())) < horizon:
            self._at.popitem(last=False)
