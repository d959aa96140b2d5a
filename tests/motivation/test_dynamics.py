"""The closed form under the model: roots of the rate, the clipped walk, exact steps."""

from __future__ import annotations

import itertools
import math
from datetime import timedelta

import numpy as np
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from motivation.dynamics import (
    DAY_S,
    OMEGA,
    apply,
    clipped_walk,
    evolve,
    integral,
    pieces,
    sign_changes,
)
from tests.motivation.strategies import instants, models, runnings, states, stimuli

rates = st.floats(-0.05, 0.05)  # points per second: up to 180 points an hour either way
swings = st.floats(0.0, 0.05)
peaks = st.floats(0.0, DAY_S)
clock = st.floats(1.7e9, 1.9e9)  # wall-clock seconds around now


def rate(a: float, b: float, peak_s: float, t: float) -> float:
    return a + b * math.cos(OMEGA * (t - peak_s))


@settings(max_examples=300, deadline=None)
@given(a=rates, b=swings, peak_s=peaks, t0=clock, length=st.floats(0.0, 5 * DAY_S))
def test_sign_changes_are_the_zeros_of_the_rate(
    a: float, b: float, peak_s: float, t0: float, length: float
) -> None:
    t1 = t0 + length
    roots = sign_changes(a, b, peak_s, t0, t1)
    assert roots == sorted(roots)
    assert all(t0 < r < t1 for r in roots)
    for r in roots:
        # the time itself is known to ~1e-7 s at this clock: the rate there is that close to 0
        assert abs(rate(a, b, peak_s, r)) <= b * OMEGA * 1e-6 + 1e-15
    # between two cuts the rate keeps one sign (sampled; the zeros are the cuts)
    cuts = [t0, *roots, t1]
    for u0, u1 in itertools.pairwise(cuts):
        if u1 - u0 < 1e-3:
            continue
        samples = [rate(a, b, peak_s, u0 + (u1 - u0) * f) for f in (0.01, 0.25, 0.5, 0.75, 0.99)]
        tiny = 1e-9 * max(b, abs(a))
        assert all(s >= -tiny for s in samples) or all(s <= tiny for s in samples)
    # two zeros a day when |a| < b, none otherwise
    if b > 0 and abs(a) < b:
        assert len(roots) <= 2 * math.ceil(length / DAY_S) + 2
        if length >= DAY_S:
            assert len(roots) >= 2 * math.floor(length / DAY_S)
    else:
        assert roots == []


@settings(max_examples=300, deadline=None)
@given(
    start=st.floats(0.0, 100.0),
    changes=st.lists(
        st.one_of(st.floats(-1.0, 1.0), st.floats(-150.0, 150.0)), min_size=0, max_size=300
    ),
)
def test_clipped_walk_equals_a_loop_of_apply(start: float, changes: list[float]) -> None:
    walk = clipped_walk(start, np.array(changes, dtype=np.float64))
    value, expected = start, []
    for change in changes:
        value = apply(value, change)
        expected.append(value)
    np.testing.assert_allclose(walk, expected, rtol=0, atol=1e-9)
    assert np.all((walk >= 0.0) & (walk <= 100.0))


@settings(max_examples=150, deadline=None)
@given(
    low=st.floats(0.0, 50.0),
    room=st.floats(0.0, 50.0),
    part=st.floats(0.0, 1.0),
    changes=st.lists(st.floats(-80.0, 80.0), max_size=100),
)
def test_clipped_walk_with_other_walls(
    low: float, room: float, part: float, changes: list[float]
) -> None:
    high = low + room
    start = low + part * room
    walk = clipped_walk(start, np.array(changes, dtype=np.float64), low, high)
    value, expected = start, []
    for change in changes:
        value = min(high, max(low, value + change))
        expected.append(value)
    np.testing.assert_allclose(walk, expected, rtol=0, atol=1e-9)


@settings(max_examples=300, deadline=None)
@given(
    drive=st.floats(0.0, 100.0),
    a=rates,
    b=swings,
    peak_s=peaks,
    t0=clock,
    length=st.floats(0.0, 3 * DAY_S),
    cut=st.floats(0.0, 1.0),
)
def test_an_interval_split_anywhere_gives_the_same_drive(
    drive: float, a: float, b: float, peak_s: float, t0: float, length: float, cut: float
) -> None:
    """The exactness argument: evolving to t1 equals evolving to any t and then to t1."""
    t1 = t0 + length
    t = t0 + cut * length
    whole = evolve(drive, a, b, peak_s, t0, t1)
    halves = evolve(evolve(drive, a, b, peak_s, t0, t), a, b, peak_s, t, t1)
    assert abs(whole - halves) <= 1e-6
    assert 0.0 <= whole <= 100.0


@settings(max_examples=200, deadline=None)
@given(a=rates, b=swings, peak_s=peaks, t0=clock, length=st.floats(0.0, 3 * DAY_S))
def test_pieces_are_one_signed_and_add_up(
    a: float, b: float, peak_s: float, t0: float, length: float
) -> None:
    parts = pieces(a, b, peak_s, t0, t0 + length)
    total = integral(a, b, peak_s, t0, t0 + length)
    assert math.isclose(sum(parts), total, abs_tol=1e-6)
    if a >= b:
        assert all(p >= 0.0 for p in parts)
    if a <= -b:
        assert all(p <= 0.0 for p in parts)


@settings(max_examples=40, deadline=None)
@given(data=st.data(), dt=st.floats(0.0, 4 * DAY_S), parts=st.integers(2, 50))
def test_one_step_equals_many_smaller_ones(data: st.DataObject, dt: float, parts: int) -> None:
    """``step`` is exact: one step over dt, or dt cut in pieces, give the same drives."""
    model = data.draw(models())
    state = data.draw(states(model))
    inputs = data.draw(stimuli(model, instant=False))
    running = data.draw(runnings(model))
    start = data.draw(instants())
    end = start + timedelta(seconds=dt)
    # a step across a daylight-saving change is taken in the new offset: not the same
    assume(start.astimezone(model.zone).utcoffset() == end.astimezone(model.zone).utcoffset())
    once = model.step(state, dt, inputs, running, end)
    many = state
    for k in range(parts):
        now = start + timedelta(seconds=dt * (k + 1) / parts)
        span = (now - (start + timedelta(seconds=dt * k / parts))).total_seconds()
        many = model.step(many, span, inputs, running, now)
    np.testing.assert_allclose(once.drives, many.drives, rtol=0, atol=1e-6)
