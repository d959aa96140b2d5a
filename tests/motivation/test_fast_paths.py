"""The tick's shortcuts give the numbers of the plain code, bit for bit (issue 14).

``step`` works out each drive's rate once per inputs (a memo) and skips ``evolve``'s
calls when the rate cannot turn; ``snapshot`` rounds with ``round3``; a prediction
skips its run when ``dominance_holds`` shows that nothing can change. Same seeds must
give the same decisions, so these are compared with ``==``, not within a tolerance.
"""

from __future__ import annotations

import math
from datetime import UTC, datetime, timedelta

import numpy as np
from hypothesis import event, given, settings
from hypothesis import strategies as st

from motivation import (
    NO_DOMINANT,
    MotivationModel,
    MotivationState,
    Percepts,
    Stimuli,
    dominance_holds,
    simulate,
)
from motivation.dynamics import evolve
from motivation.model import day_seconds, round3
from tests.motivation.strategies import instants, models, runnings, states, stimuli

NIGHT = datetime(2026, 11, 23, 23, 0, tzinfo=UTC)


def plain_step(
    model: MotivationModel,
    state: MotivationState,
    dt: float,
    inputs: Stimuli,
    running: str | None,
    now: datetime,
) -> MotivationState:
    """``step`` as it was written before the shortcuts: ``evolve`` for every drive."""
    end = day_seconds(now, model.zone)
    start = end - dt
    growth = model.net_growth(inputs, running).tolist()
    swing = model.swing(running).tolist()
    evolved = []
    for i, drive in enumerate(state.drives.tolist()):
        drive = max(0.0, drive - float(inputs.instant[i]))
        peak = float(model.table.peak_s[i])
        evolved.append(evolve(drive, growth[i], swing[i], peak, start, end))
    drives = np.array(evolved)
    dominant = model.next_dominant(state.dominant, drives, inputs.levels)
    return MotivationState(drives, inputs.levels, dominant)


@settings(max_examples=150, deadline=None)
@given(st.data())
def test_step_is_the_plain_step_bit_for_bit(data: st.DataObject) -> None:
    model = data.draw(models())
    state = data.draw(states(model))
    now = data.draw(instants())
    # two inputs taken in turn, and a running behavior that changes: the memo must follow
    inputs = [data.draw(stimuli(model)), data.draw(stimuli(model))]
    plain = state
    for k in range(6):
        dt = data.draw(st.sampled_from([0.5, 0.5, 3.0, 300.0, 7200.0]))
        running = data.draw(runnings(model))
        now += timedelta(seconds=dt)
        given_inputs = inputs[k % 2]
        state = model.step(state, dt, given_inputs, running, now)
        plain = plain_step(model, plain, dt, given_inputs, running, now)
        assert state.drives.tolist() == plain.drives.tolist()
        assert state.dominant == plain.dominant


@settings(max_examples=200, deadline=None)
@given(st.data())
def test_step_is_the_plain_step_at_the_walls_and_outside_them(data: st.DataObject) -> None:
    """Drives at 0, -0.0 and 100, states made by hand outside [0, 100] and negative
    caresses: the step's shortcut must still give the plain step's floats, sign of zero
    included (compared as ``repr``)."""
    model = data.draw(models())
    n = len(model.names)
    edges = st.sampled_from([0.0, -0.0, 100.0, -5.0, 150.0, 1e-300])
    drives = data.draw(st.lists(st.one_of(edges, st.floats(-50.0, 150.0)), min_size=n, max_size=n))
    levels = np.array(data.draw(st.lists(st.floats(0.0, 1.0), min_size=n, max_size=n)))
    state = MotivationState(np.array(drives), levels, NO_DOMINANT)
    instant = data.draw(st.lists(st.sampled_from([0.0, 0.0, -3.0, 2.0]), min_size=n, max_size=n))
    inputs = Stimuli(levels, np.zeros(n), np.array(instant))
    running = data.draw(runnings(model))
    now = data.draw(instants())
    dt = data.draw(st.sampled_from([0.5, 3.0, 300.0]))
    ours = model.step(state, dt, inputs, running, now)
    plain = plain_step(model, state, dt, inputs, running, now)
    assert [repr(v) for v in ours.drives.tolist()] == [repr(v) for v in plain.drives.tolist()]
    assert ours.dominant == plain.dominant


@given(st.floats(allow_nan=True, allow_infinity=True))
def test_round3_is_round(value: float) -> None:
    ours, theirs = round3(value), round(value, 3)
    if math.isnan(theirs):
        assert math.isnan(ours)
    else:
        assert ours == theirs and math.copysign(1.0, ours) == math.copysign(1.0, theirs)


def test_round3_near_halves_and_zeros() -> None:
    """Ties and their neighbours, where the product in floats could mislead."""
    values = [0.0, -0.0, 2.675, 1.0005, 99.9995, 0.0005, 5e-324, 1e15, 1e300]
    for k in range(0, 200_001, 7):
        tie = k / 2000
        values += [tie, math.nextafter(tie, 0.0), math.nextafter(tie, 1e9)]
    for value in values:
        ours = round3(value)
        assert ours == round(value, 3)
        assert math.copysign(1.0, ours) == math.copysign(1.0, round(value, 3))


@settings(max_examples=400, deadline=None)
@given(st.data())
def test_a_dominance_the_bound_keeps_is_kept_at_every_tick(data: st.DataObject) -> None:
    """Where ``dominance_holds`` says the dominant drive stays, a run at the tick rate
    finds it at every tick. The longest horizon the bound allows is tried too: there a
    drive may come within a hair of its threshold or satiation level."""
    model = data.draw(models())
    state = data.draw(states(model))
    inputs = data.draw(stimuli(model))
    running = data.draw(runnings(model))
    now = data.draw(instants())
    seconds = data.draw(st.sampled_from([0.5, 30.0, 600.0, 3600.0]))
    if not dominance_holds(model, state, inputs, running, seconds):
        event("does not hold")
        return
    while dominance_holds(model, state, inputs, running, 2 * seconds) and seconds < 86_400:
        seconds *= 2  # towards the edge of what the bound allows
    event("holds")
    run = simulate(model, state, now, seconds, inputs, running=running)
    assert set(run.dominant.tolist()) <= {state.dominant}


def test_the_bound_holds_for_a_quiet_night_and_not_near_a_threshold() -> None:
    """The shipped drives at rest, far below their thresholds, for half an hour: it holds,
    and the run agrees. A drive a point under its threshold and rising: it does not."""
    model = MotivationModel()
    inputs = model.stimuli(Percepts(False, None, None))
    low = np.array([5.0] * len(model.names))
    quiet = MotivationState(
        low, inputs.levels, model.next_dominant(NO_DOMINANT, low, inputs.levels)
    )
    assert quiet.dominant == NO_DOMINANT
    assert dominance_holds(model, quiet, inputs, None, 1800.0)
    run = simulate(model, quiet, NIGHT, 1800.0, inputs)
    assert set(run.dominant.tolist()) == {NO_DOMINANT}
    rising = int(np.argmax(model.net_growth(inputs, None)))
    near = low.copy()
    near[rising] = float(model.table.threshold[rising]) - 1.0
    edge = MotivationState(near, inputs.levels, NO_DOMINANT)
    assert not dominance_holds(model, edge, inputs, None, 1800.0)
    assert dominance_holds(model, edge, inputs, None, 0.5)
