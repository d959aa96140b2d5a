"""``step``'s shortcut gives the numbers of the plain code, bit for bit.

``step`` works out each drive's rate once per inputs (a memo) and skips ``evolve``'s
calls when the rate cannot turn. Same seeds must give the same decisions, so the two
are compared with ``==``, not within a tolerance.
"""

from __future__ import annotations

from datetime import datetime, timedelta

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from motivation import NO_DOMINANT, MotivationModel, MotivationState, Stimuli
from motivation.dynamics import evolve
from motivation.model import day_seconds
from tests.motivation.strategies import instants, models, runnings, states, stimuli


def plain_step(
    model: MotivationModel,
    state: MotivationState,
    dt: float,
    inputs: Stimuli,
    running: str | None,
    now: datetime,
) -> MotivationState:
    """``step`` without its shortcut: ``evolve`` for every drive."""
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
