"""``--chooser``: the robot's own choices by the decision system or by a baseline.

The baselines are injected through the simulator's wiring (the controller's chooser is
swapped); the participants and seeds stay the same, so the runs pair session by session.
"""

from __future__ import annotations

import json
import random
from datetime import UTC, datetime

import pytest

from dms.cli import main
from memory import ActivityChooser, PreferenceModel
from memory.profile import ActivityScore, Profile
from sim.adaptation import population_ranking
from sim.baselines import BaselineChooser
from sim.study import run_study, study_settings

SESSIONS, MINUTES = 6, 12.0
NOW = datetime(2026, 11, 23, 9, 0, tzinfo=UTC)


def _robot_choices(chooser: str) -> list[tuple[str, str | None]]:
    result = run_study(
        SESSIONS,
        MINUTES,
        "low",
        3,
        study_settings(),
        chooser=chooser,  # type: ignore[arg-type]
        record_decisions=True,
    )
    return [
        (row.participant, row.decision.activity)
        for row in result.decisions
        if row.decision.action == "start" and row.decision.chosen_by == "robot"
    ]


def test_the_chooser_flag_changes_the_robots_choices() -> None:
    learned, fixed = _robot_choices("dms"), _robot_choices("fixed")
    assert learned and fixed
    assert learned != fixed
    # The fixed cycle goes through the activities in order, whoever sits there.
    assert fixed[0][1] == "multimedia"


def test_a_random_chooser_is_cancelled_more_than_the_decision_system() -> None:
    runs = {
        chooser: run_study(
            SESSIONS,
            MINUTES,
            "low",
            1,
            study_settings(),
            chooser=chooser,
        )
        for chooser in ("dms", "random", "oracle")
    }
    liking = {
        name: sum(v for s in r.sessions for v in s.robot_choice_liking)
        / max(1, sum(len(s.robot_choice_liking) for s in r.sessions))
        for name, r in runs.items()
    }
    cancels = {name: sum(s.cancels for s in r.sessions) for name, r in runs.items()}
    assert cancels["random"] > cancels["dms"], cancels
    assert liking["oracle"] > liking["dms"] > liking["random"], liking


def test_compare_pairs_two_choosers(capsys: pytest.CaptureFixture[str]) -> None:
    args = ["sim", "compare", "--chooser-a", "dms", "--chooser-b", "least_liked"]
    args += ["--sessions", "4", "--minutes", "10", "--json"]
    assert main(args) == 0
    metrics = json.loads(capsys.readouterr().out)["metrics"]
    liking = metrics["robot_choice_liking"]
    assert liking["b"] < liking["a"]
    assert liking["ci"][1] < 0.0  # the worst choice is worse beyond the noise


def test_popular_offers_everyone_the_training_datas_favourite_first() -> None:
    top = population_ranking()[0]
    firsts: dict[str, str | None] = {}
    for participant, activity in _robot_choices("popular"):
        firsts.setdefault(participant, activity)
    assert len(firsts) >= 3
    assert set(firsts.values()) == {top}, firsts


def test_greedy_takes_the_learned_rankings_best_whatever_the_draws() -> None:
    chooser = ActivityChooser(PreferenceModel.from_seed())
    profile = Profile.model_validate(
        {
            "user_id": "ann",
            "created_at": NOW,
            "updated_at": NOW,
            "scores": {
                "bingo": ActivityScore(completions=2, feedback_count=2, feedback_sum=2.0),
                "quiz": ActivityScore(completions=2, feedback_count=2, feedback_sum=1.5),
            },
        }
    )
    means = {name: a / (a + b) for name, (a, b) in chooser.beliefs(profile).items()}
    greedy = BaselineChooser(chooser, "greedy", lambda _user: None, seed=0)
    best = max(means, key=means.__getitem__)
    assert best == "bingo"  # rated 5 of 5 twice
    for draw in range(20):  # the daemon's random stream does not move it
        assert greedy.choose(profile, random.Random(draw)).activity == best
    assert sorted(means, key=means.__getitem__)[-2] == "quiz"  # rated 4 of 5 twice
    assert greedy.choose(profile, random.Random(0), exclude={best}).activity == "quiz"


def test_compare_reports_every_metric_per_visit(capsys: pytest.CaptureFixture[str]) -> None:
    args = ["sim", "compare", "--chooser-a", "popular", "--chooser-b", "dms"]
    args += ["--seeds", "0-1", "--population", "heldout", "--repeat", "2"]
    args += ["--sessions", "3", "--minutes", "8", "--json"]
    assert main(args) == 0
    out = json.loads(capsys.readouterr().out)
    assert [v["visit"] for v in out["visits"]] == [1, 2]
    for visit in out["visits"]:
        assert set(visit["metrics"]) == set(out["metrics"])
    # The pooled mean lies between the visits' means (each visit has the same people).
    pooled = out["metrics"]["robot_choice_liking"]["a"]
    visits = [v["metrics"]["robot_choice_liking"]["a"] for v in out["visits"]]
    assert min(visits) - 1e-9 <= pooled <= max(visits) + 1e-9
