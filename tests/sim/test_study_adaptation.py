"""The robot learns what each returning participant likes (issue 12, item 6).

With ``--repeat`` every participant comes back; after each visit the daemon's predicted
ranking of the eight entertainment activities (its chooser's expected liking) is
compared with the participant's hidden true ranking by Kendall's tau. The daemon is
told nothing of the truth: it learns from the participant's features (the opening
questions), ratings, completions and cancellations.
"""

from __future__ import annotations

import pytest

from sim.study import kendall_tau, run_study, study_settings


def test_kendall_tau_compares_the_same_activities_by_position() -> None:
    truth = ["a", "b", "c", "d"]
    assert kendall_tau(truth, truth) == pytest.approx(1.0)
    assert kendall_tau(list(reversed(truth)), truth) == pytest.approx(-1.0)
    assert kendall_tau(["b", "a", "c", "d"], truth) == pytest.approx(4 / 6)


def test_tau_reaches_0_7_by_the_fifth_visit_and_grows() -> None:
    # 20 participants: a participant's tau spreads by about 0.15, so fewer would test the
    # luck of the draw more than the learning (the figure in docs/adaptation.png has 30).
    result = run_study(20, 30.0, "moderate", 0, study_settings(), repeat=5)
    taus = result.adaptation()["kendall_tau_by_session"]
    assert len(taus) == 5
    assert taus[4] >= 0.7, taus
    assert taus[4] > taus[0], taus  # the visits teach it something the features did not
