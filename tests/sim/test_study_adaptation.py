"""The robot learns what each returning participant likes.

With ``--repeat`` every participant comes back; after each visit the daemon's predicted
ranking of the eight entertainment activities (its chooser's expected liking) is
compared with the participant's hidden true ranking by Kendall's tau, beside two
rankings that learn nothing from the visits (the training data's mean ranking, the
learner's prediction from features alone). The daemon is told nothing of the truth.
"""

from __future__ import annotations

import pytest

from sim.study import kendall_tau, run_study, study_settings


def test_kendall_tau_compares_the_same_activities_by_position() -> None:
    truth = ["a", "b", "c", "d"]
    assert kendall_tau(truth, truth) == pytest.approx(1.0)
    assert kendall_tau(list(reversed(truth)), truth) == pytest.approx(-1.0)
    assert kendall_tau(["b", "a", "c", "d"], truth) == pytest.approx(4 / 6)


def test_visits_teach_the_robot_more_than_the_features_on_held_out_participants() -> None:
    # Held-out tastes: the features say nothing of them, so what the robot gets right
    # after the visits it learnt from them. 10 participants, 3 short visits: the
    # machinery, not the size of the effect (docs/benchmarks.md has 30 x 10 visits).
    result = run_study(10, 20.0, "moderate", 0, study_settings(), repeat=3, population="heldout")
    by_visit = result.adaptation()
    taus = by_visit["kendall_tau_by_session"]
    features = by_visit["tau_features_by_session"]
    assert len(taus) == 3
    assert taus[2] > taus[0], taus
    assert taus[2] > features[2], (taus, features)
