"""Exact integration of one drive between inputs: the closed form behind every step.

While the inputs stay the same, a drive moves at

    dD/dt = a + b * cos(omega * (t - peak))

(``a`` the mean growth minus what satisfies it, ``b`` the daily swing, ``omega`` one
turn a day, ``t`` in local seconds) and stays inside [0, 100]. Between two zeros of
the right-hand side the drive moves one way only, so there the clipped solution is
the unclipped integral clipped once. Splitting an interval at those zeros (found in
closed form) gives the exact solution for any interval length; the daemon's 0.5 s
ticks and a month-long jump go through the same code. Everything here is pure.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
from numpy.typing import NDArray

DAY_S = 86_400.0
OMEGA = 2.0 * math.pi / DAY_S
TWO_PI = 2.0 * math.pi
LOW, HIGH = 0.0, 100.0

FloatArray = NDArray[np.float64]


def integral(a: float, b: float, peak_s: float, t0: float, t1: float) -> float:
    """The unclipped change of a drive over [t0, t1]."""
    return a * (t1 - t0) + (b / OMEGA) * (
        math.sin(OMEGA * (t1 - peak_s)) - math.sin(OMEGA * (t0 - peak_s))
    )


def integrals(a: FloatArray | float, b: float, peak_s: float, times: FloatArray) -> FloatArray:
    """The unclipped change over each interval [times[j], times[j + 1]] (vectorized)."""
    wave = np.sin(OMEGA * (times - peak_s))
    return np.asarray(a * np.diff(times) + (b / OMEGA) * np.diff(wave), dtype=np.float64)


def signed(change: float, a: float, b: float, peak_s: float, t0: float, t1: float) -> float:
    """A change over [t0, t1], where the rate keeps one sign, given that sign.

    The sine of a wall-clock time (about 1e5 radians) carries rounding of about 1e-11, so
    a change near a zero of the rate can come out with the wrong sign; a drive with
    nothing satisfying it must never fall, not even by 1e-12.
    """
    if a >= b:
        return max(change, 0.0)
    if a <= -b:
        return min(change, 0.0)
    rising = a + b * math.cos(OMEGA * (0.5 * (t0 + t1) - peak_s)) >= 0.0
    return max(change, 0.0) if rising else min(change, 0.0)


def signed_integrals(a: float, b: float, peak_s: float, times: FloatArray) -> FloatArray:
    """``integrals`` with each change given the sign of the rate inside its interval.

    The same rule as ``signed``; an interval where the rate changes sign must be split
    first (``pieces``), its value here is meaningless.
    """
    changes = integrals(a, b, peak_s, times)
    if a >= b:
        return np.maximum(changes, 0.0)
    if a <= -b:
        return np.minimum(changes, 0.0)
    middle = 0.5 * (times[:-1] + times[1:])
    rising = a + b * np.cos(OMEGA * (middle - peak_s)) >= 0.0
    return np.where(rising, np.maximum(changes, 0.0), np.minimum(changes, 0.0))


def sign_changes(a: float, b: float, peak_s: float, t0: float, t1: float) -> list[float]:
    """The times strictly inside (t0, t1) where a + b*cos(omega*(t - peak)) is zero, sorted."""
    if b <= 0.0 or abs(a) >= b or t1 <= t0:
        return []
    alpha = math.acos(-a / b)
    theta0, theta1 = OMEGA * (t0 - peak_s), OMEGA * (t1 - peak_s)
    found: list[float] = []
    for base in (alpha, -alpha):
        k = math.floor((theta0 - base) / TWO_PI) + 1
        while (theta := base + TWO_PI * k) < theta1:
            if theta > theta0:
                found.append(peak_s + theta / OMEGA)
            k += 1
    found.sort()
    return found


def pieces(a: float, b: float, peak_s: float, t0: float, t1: float) -> list[float]:
    """The changes over [t0, t1] split where the drive turns, each one-signed."""
    cuts = [t0, *sign_changes(a, b, peak_s, t0, t1), t1]
    return [
        signed(integral(a, b, peak_s, u0, u1), a, b, peak_s, u0, u1)
        for u0, u1 in itertools.pairwise(cuts)
    ]


def apply(drive: float, change: float) -> float:
    """A one-signed change applied to a drive that stays in [0, 100]."""
    return min(HIGH, max(LOW, drive + change))


def evolve(drive: float, a: float, b: float, peak_s: float, t0: float, t1: float) -> float:
    """The drive at t1, exactly, from its value at t0 under constant inputs."""
    turns = sign_changes(a, b, peak_s, t0, t1)
    if not turns:  # a tick's half second almost always: one piece, as ``pieces`` gives
        return apply(drive, signed(integral(a, b, peak_s, t0, t1), a, b, peak_s, t0, t1))
    for change in pieces(a, b, peak_s, t0, t1):
        drive = apply(drive, change)
    return drive


def clipped_walk(
    start: float, changes: FloatArray, low: float = LOW, high: float = HIGH
) -> FloatArray:
    """``out[j]`` after applying ``changes[0..j]`` one by one, each clipped into [low, high].

    The same as a loop of ``apply`` but in numpy: with only the lower wall, the walk is
    ``y - min(0, running min of y)`` (the Lindley form of a queue); when that crosses the
    upper wall the walk is pinned there and continues under the upper wall's mirror form,
    and so on. Walls are hit a few times a day, so this stays linear in practice.
    """
    out = np.empty(len(changes), dtype=np.float64)
    position, value, under_lower = 0, start, True
    while position < len(changes):
        path = value + np.cumsum(changes[position:])
        if under_lower:
            walk = path - np.minimum(0.0, np.minimum.accumulate(path - low))
            crossing = np.flatnonzero(walk > high)
        else:
            walk = path - np.maximum(0.0, np.maximum.accumulate(path - high))
            crossing = np.flatnonzero(walk < low)
        if crossing.size == 0:
            out[position:] = walk
            break
        first = int(crossing[0])
        out[position : position + first] = walk[:first]
        value = high if under_lower else low
        out[position + first] = value
        position += first + 1
        under_lower = not under_lower
    return out
