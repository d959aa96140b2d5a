"""Where a simulated user's face is: seated in front of the Mini, leaning and shifting.

The paper's users sit at a table in front of the robot. A person does not stay still
for half an hour: every so often they lean, sit back or move their chair. :class:`Seat`
gives the face's position in the robot's base frame at any ``now``: it stays put, then
moves over a second or two to a new place within reach of the robot's camera. Its
random draws come from its own generator, so giving users a body changes nothing else
a seeded simulation draws. Positions are rounded to a centimetre, as a face tracker's
would be useful to, so a still face is one unchanged message.
"""

from __future__ import annotations

import random
from dataclasses import dataclass
from datetime import datetime, timedelta

Position = tuple[float, float, float]

HOME: Position = (0.65, 0.0, 0.32)
"""A seated adult's face: 65 cm in front of the robot, 32 cm above its base (the Mini
stands on the table, the face is above the table's edge)."""


@dataclass(frozen=True, slots=True)
class SeatSettings:
    """How much and how often a seated person moves."""

    still_s: tuple[float, float] = (20.0, 90.0)
    """Seconds between two moves."""
    move_s: tuple[float, float] = (0.8, 2.0)
    """How long a move takes."""
    x: tuple[float, float] = (0.5, 0.85)
    y: tuple[float, float] = (-0.3, 0.3)
    z: tuple[float, float] = (0.25, 0.4)


class Seat:
    """A face that moves now and then; ``face(now)`` with ``now`` never going back."""

    def __init__(
        self,
        now: datetime,
        seed: str | int,
        settings: SeatSettings | None = None,
        home: Position = HOME,
    ) -> None:
        self.settings = settings or SeatSettings()
        self._rng = random.Random(seed)
        self._from: Position = home
        self._head_for(home)
        self.sit(now)

    def sit(self, now: datetime) -> None:
        """Sit down again at ``now`` where the face was last: the next move comes after
        a still spell from now (no catching up on the moves of the time away)."""
        self._from = self._to
        self._start = self._end = now
        self._next = now + timedelta(seconds=self._rng.uniform(*self.settings.still_s))

    def face(self, now: datetime) -> Position:
        """The face's position at ``now`` (metres, base frame, rounded to 1 cm)."""
        while now >= self._next:
            self._move(self._next)
        if now >= self._end:
            return self._rest
        span = (self._end - self._start).total_seconds()
        done = (now - self._start).total_seconds() / span if span > 0 else 1.0
        (x0, y0, z0), (x1, y1, z1) = self._from, self._to
        return _rounded((x0 + (x1 - x0) * done, y0 + (y1 - y0) * done, z0 + (z1 - z0) * done))

    def move_to(self, where: Position, now: datetime, seconds: float = 0.0) -> None:
        """Move the face to ``where`` over ``seconds`` from ``now`` (a scripted move)."""
        self._from = self.face(now)
        self._head_for(where)
        self._start = now
        self._end = now + timedelta(seconds=seconds)

    def _head_for(self, where: Position) -> None:
        """Aim the move under way at ``where``; the face rests there, rounded as ``face``
        reports it."""
        self._to = where
        self._rest = _rounded(where)

    def _move(self, when: datetime) -> None:
        s = self.settings
        self._from = self._to
        self._head_for((self._rng.uniform(*s.x), self._rng.uniform(*s.y), self._rng.uniform(*s.z)))
        self._start = when
        self._end = when + timedelta(seconds=self._rng.uniform(*s.move_s))
        self._next = self._end + timedelta(seconds=self._rng.uniform(*s.still_s))


def _rounded(position: Position) -> Position:
    x, y, z = position
    return (round(x, 2), round(y, 2), round(z, 2))
