"""Invariants of the motivation model, for any configuration, state, inputs and clock.

The reference is what the daemon does: ``step`` once every 0.5 s tick. ``advance`` and
``simulate`` must give the same states (drives within 1e-6 points, the same dominant
drive at every tick), with a fixed running behavior and with the behavior following
the dominant motivation as an idle robot's does.
"""

from __future__ import annotations

import itertools
from datetime import datetime, timedelta

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from motivation import MotivationModel, MotivationState, Stimuli, advance, simulate
from motivation.model import NO_DOMINANT
from tests.motivation.strategies import instants, models, runnings, states, stimuli

TICK = 0.5
DRIVE_ATOL = 1e-6
"""How far ``advance``/``simulate`` may be from the tick-by-tick loop, in drive points."""


def step_loop(
    model: MotivationModel,
    state: MotivationState,
    start: datetime,
    duration: float,
    inputs: Stimuli,
    running: str | None = None,
    follow: bool = False,
) -> list[MotivationState]:
    """The daemon's way: one ``step`` per tick (then one for the rest); the state after each."""
    ticks = int(duration // TICK)
    out: list[MotivationState] = []
    now = start
    for k in range(ticks):
        now = start + timedelta(seconds=(k + 1) * TICK)
        doing = model.behavior(state) if follow else running
        state = model.step(state, TICK, inputs if k == 0 else inputs.without_instant(), doing, now)
        out.append(state)
    rest = duration - ticks * TICK
    if rest > 1e-9 or ticks == 0:
        doing = model.behavior(state) if follow else running
        first = inputs if ticks == 0 else inputs.without_instant()
        out.append(model.step(state, rest, first, doing, start + timedelta(seconds=duration)))
    return out


def assert_same(left: MotivationState, right: MotivationState) -> None:
    np.testing.assert_allclose(left.drives, right.drives, rtol=0, atol=DRIVE_ATOL)
    assert left.dominant == right.dominant


# ---------------------------------------------------------------------- bounds


@settings(max_examples=200, deadline=None)
@given(data=st.data(), dt=st.one_of(st.floats(0, 86_400.0), st.floats(0, 1e8)))
def test_drives_stay_in_range_for_any_step(data: st.DataObject, dt: float) -> None:
    model = data.draw(models())
    state = data.draw(states(model))
    inputs = data.draw(stimuli(model))
    running = data.draw(runnings(model))
    now = data.draw(instants())
    after = model.step(state, dt, inputs, running, now)
    assert np.all(after.drives >= 0.0) and np.all(after.drives <= 100.0)
    assert after.dominant == NO_DOMINANT or 0 <= after.dominant < len(model.names)
    assert 0.0 <= model.wellbeing(after.drives) <= 100.0


@settings(max_examples=30, deadline=None)
@given(data=st.data(), follow=st.booleans())
def test_drives_stay_in_range_over_long_runs(data: st.DataObject, follow: bool) -> None:
    """Up to 20 days with a fixed behavior; up to 6 h following the dominant motivation.

    (A configuration with no hysteresis can switch every tick, and ``simulate`` pays a
    few tens of microseconds per switch: weeks of that would only slow the suite.)
    """
    duration = data.draw(st.floats(0, 6 * 3600.0 if follow else 20 * 86_400.0))
    model = data.draw(models())
    state = data.draw(states(model))
    run = simulate(
        model,
        state,
        data.draw(instants()),
        duration,
        data.draw(stimuli(model)),
        running=data.draw(runnings(model)),
        follow=follow,
        every=600,
    )
    assert np.all(run.drives >= 0.0) and np.all(run.drives <= 100.0)
    assert np.all(run.final.drives >= 0.0) and np.all(run.final.drives <= 100.0)
    assert np.all((run.wellbeing >= 0.0) & (run.wellbeing <= 100.0))


@settings(max_examples=150, deadline=None)
@given(data=st.data(), dts=st.lists(st.floats(0, 20_000.0), min_size=1, max_size=12))
def test_with_nothing_satisfying_it_a_drive_never_falls(
    data: st.DataObject, dts: list[float]
) -> None:
    model = data.draw(models())
    state = data.draw(states(model))
    inputs = data.draw(stimuli(model))
    calm = Stimuli(inputs.levels, np.zeros_like(inputs.levels), np.zeros_like(inputs.levels))
    now = data.draw(instants())
    for dt in dts:
        now += timedelta(seconds=dt)
        after = model.step(state, dt, calm, None, now)
        assert np.all(after.drives >= state.drives)
        state = after


# ---------------------------------------------------------------------- advance = stepping


@settings(max_examples=40, deadline=None)
@given(data=st.data(), duration=st.floats(0, 1800.0))
def test_advance_and_samples_equal_stepping_every_tick(
    data: st.DataObject, duration: float
) -> None:
    model = data.draw(models())
    state = data.draw(states(model))
    inputs = data.draw(stimuli(model))
    running = data.draw(runnings(model))
    start = data.draw(instants())
    loop = step_loop(model, state, start, duration, inputs, running)
    final = advance(model, state, duration, inputs, running, start)
    assert_same(final, loop[-1] if loop else state)
    run = simulate(model, state, start, duration, inputs, running=running, every=1)
    ticks = int(duration // TICK)
    assert run.ticks == ticks and len(run.drives) == ticks
    np.testing.assert_allclose(run.seconds, TICK * np.arange(1, ticks + 1))
    expected = np.array([s.drives for s in loop[:ticks]]).reshape(ticks, len(model.names))
    np.testing.assert_allclose(run.drives, expected, rtol=0, atol=DRIVE_ATOL)
    assert run.dominant.tolist() == [s.dominant for s in loop[:ticks]]
    for k in range(0, ticks, max(1, ticks // 20)):
        np.testing.assert_allclose(
            run.motivations[k],
            model.motivations(loop[k].drives, loop[k].levels, loop[k].dominant),
            atol=DRIVE_ATOL,
        )
        assert run.wellbeing[k] == pytest.approx(model.wellbeing(loop[k].drives), abs=DRIVE_ATOL)


@settings(max_examples=40, deadline=None)
@given(data=st.data(), duration=st.floats(0, 1800.0))
def test_following_the_dominant_motivation_equals_the_loop(
    data: st.DataObject, duration: float
) -> None:
    model = data.draw(models())
    state = data.draw(states(model))
    inputs = data.draw(stimuli(model))
    start = data.draw(instants())
    loop = step_loop(model, state, start, duration, inputs, follow=True)
    # a start given in the robot's own zone counts the same elapsed ticks
    local_start = start.astimezone(model.zone)
    run = simulate(model, state, local_start, duration, inputs, follow=True, every=1)
    assert_same(run.final, loop[-1] if loop else state)
    ticks = run.ticks
    expected = np.array([s.drives for s in loop[:ticks]]).reshape(ticks, len(model.names))
    np.testing.assert_allclose(run.drives, expected, rtol=0, atol=DRIVE_ATOL)
    assert run.dominant.tolist() == [s.dominant for s in loop[:ticks]]
    behaviors = [model.behavior(s) for s in [state, *loop[:ticks]]]
    changes = sum(a != b for a, b in itertools.pairwise(behaviors))
    assert run.switches == changes


# ---------------------------------------------------------------------- hysteresis


@settings(max_examples=150, deadline=None)
@given(data=st.data(), dts=st.lists(st.floats(0, 3600.0), min_size=1, max_size=30))
def test_noise_below_the_margin_never_changes_the_dominant_motivation(
    data: st.DataObject, dts: list[float]
) -> None:
    """Drives held still (nothing grows); stimuli wobble by less than half the margin each side.

    A challenger then never gains the margin on the dominant drive, so the dominant drive
    chosen at the base stimuli stays, whatever the wobble and however long.
    """
    model = data.draw(models(still=True))
    n = len(model.names)
    drives = np.array(data.draw(st.lists(st.floats(0, 100.0), min_size=n, max_size=n)))
    base = np.array(data.draw(st.lists(st.floats(0, 1.0), min_size=n, max_size=n)))
    first = model.next_dominant(NO_DOMINANT, drives, base)
    state = MotivationState(drives, base, first)
    margin = model.config.hysteresis
    now = data.draw(instants())
    for dt in dts:
        unit = np.array(data.draw(st.lists(st.floats(-1.0, 1.0), min_size=n, max_size=n)))
        # |alpha_i * (w_i - base_i)| < margin / 2, and w_i stays in [0, 1]
        reach = np.minimum(1.0, 0.499 * margin / np.maximum(model.table.alpha, 1e-9))
        levels = np.clip(base + unit * reach, 0.0, 1.0)
        now += timedelta(seconds=dt)
        state = model.step(state, dt, Stimuli(levels, np.zeros(n)), None, now)
        assert state.dominant == first
