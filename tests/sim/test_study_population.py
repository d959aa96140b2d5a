"""``--population``: who the participants are, and what Kendall's tau is measured against."""

from __future__ import annotations

from sim.adaptation import population_ranking
from sim.study import participants, run_study, study_settings


def test_the_population_flag_changes_the_participants() -> None:
    paper = participants(5, 0, "moderate", "paper")
    heldout = participants(5, 0, "moderate", "heldout")
    assert [p.preferences for p in paper] != [p.preferences for p in heldout]
    assert participants(5, 0, "moderate", "heldout") == heldout  # seeded
    for person in heldout:
        assert 18 <= int(person.features["age"]) <= 52


def test_tau_is_reported_beside_its_baselines_per_visit() -> None:
    result = run_study(4, 10.0, "moderate", 0, study_settings(), repeat=2, population="heldout")
    by_visit = result.adaptation()
    for key in (
        "kendall_tau_by_session",
        "tau_features_by_session",
        "tau_population_by_session",
        "cancels_per_robot_choice_by_session",
        "robot_choice_liking_by_session",
    ):
        assert len(by_visit[key]) == 2, key
    assert sorted(population_ranking()) == sorted(
        ["multimedia", "news", "weather", "quiz", "dance", "bingo", "jokes", "sayings"]
    )
    assert all(s.tau_population is not None for s in result.sessions)
