"""``--chooser``: the robot's own choices by the decision system or by a baseline.

The baselines are injected through the simulator's wiring (the controller's chooser is
swapped); the participants and seeds stay the same, so the runs pair session by session.
"""

from __future__ import annotations

import json

import pytest

from dms.cli import main
from sim.study import run_study, study_settings

SESSIONS, MINUTES = 6, 12.0


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
