"""The daemon's own Table 4 agrees with the study's on a simulated session.

The simulator builds the daemon's controller (``sim.harness``), so a simulated session
is stored with the metrics the controller measured (``dms.kernel.session_metrics``). They must
be what ``sim/study.py`` computes from the outside for the same session, by the same
definitions: one measure, two vantage points.
"""

from __future__ import annotations

import random
from datetime import UTC, datetime

import pytest

from sim.harness import Simulation
from sim.study import (
    LAUNCH_DELAY_S,
    METRICS,
    SessionObserver,
    command_handle,
    participants,
    session_value,
    study_settings,
)
from sim.user import SimulatedUser

START = datetime(2026, 11, 23, 9, 0, tzinfo=UTC)


@pytest.mark.parametrize("seed", [1, 2])
def test_stored_metrics_agree_with_the_study_observer(seed: int) -> None:
    with Simulation(study_settings(), seed=seed, start=START, launch_delay_s=LAUNCH_DELAY_S) as sim:
        observer = SessionObserver()
        sim.decision_listeners.append(observer.on_decision)
        sim.command_listeners.append(
            lambda cmd, _now: observer.on_command(command_handle(sim, cmd), sim.t)
        )
        sim.tick_listeners.append(lambda _record: observer.on_tick(sim.t))
        person = participants(1, seed, "moderate")[0]
        user = SimulatedUser(person, random.Random(seed))
        unanswered = sim.controller.counters.unanswered
        sim.seat(user)
        sim.run_for(12 * 60.0)
        sim.unseat()
        sim.run_for(1.0)  # the departure is seen and the session stored
        store = sim.stack.store
        assert store is not None
        stored = store.sessions()
        expected = observer.metrics
        unanswered = sim.controller.counters.unanswered - unanswered

    assert len(stored) == 1 and stored[0]["user"] == person.id
    metrics = stored[0]["metrics"]
    assert metrics is not None
    assert expected.activities >= 2 and expected.load_times  # a session worth comparing
    for key in METRICS:
        want = session_value(expected, key)
        got = metrics[key]
        if want is None:
            assert got is None, key
        else:
            assert got == pytest.approx(want, abs=1e-3), key
    assert metrics["activity_not_loaded"] == expected.not_loaded
    assert metrics["other"] == expected.other_failures
    assert metrics["speech_recognition_errors"] == user.stats.misrecognized
    assert metrics["user_not_answering"] == unanswered
    # From the user being ready (a few seconds after sitting down) to the departure.
    assert 12 * 60.0 - 30.0 < metrics["duration_s"] <= 12 * 60.0 + 1.0
