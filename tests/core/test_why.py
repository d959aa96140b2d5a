"""Every decision explains itself: ``Decision.why`` (issue 12, item 7)."""

from __future__ import annotations

from datetime import UTC, datetime
from pathlib import Path

from dms.config import Settings
from dms.kernel import keys
from dms.kernel.messages import Request, UserPerception
from sim.harness import Simulation

START = datetime(2026, 11, 23, 10, 0, tzinfo=UTC)
ANN = UserPerception(present=True, user_id="ann", ready=True, engagement=0.8)


def _sim(tmp: Path | None = None, rules: str | None = None) -> Simulation:
    data: dict[str, object] = {
        "controller": {"session_questions": 0, "question_every": 0, "feedback_probability": 0},
        "inputs": {"stale_after_s": {"perception/user": 30.0}},
    }
    if rules is not None and tmp is not None:
        path = tmp / "decisions.dmsl"
        path.write_text(rules)
        data["rules"] = {"files": [str(path)]}
    return Simulation(Settings.model_validate(data), seed=6, start=START)


def test_robot_choices_carry_the_mode_draw_the_preferences_and_the_drives() -> None:
    with _sim() as sim:
        sim.presence = ANN
        sim.feed(keys.PERCEPTION_USER, ANN)
        for _ in range(8):  # several choices: cancel what runs, the robot chooses again
            sim.run_for(20)
            sim.feed(keys.REQUEST, Request(action="cancel", by="app"))
            sim.tick(urgent=True)
        robot = [d.decision for d in sim.decisions if d.decision.chosen_by == "robot"]
        robot_starts = [d for d in robot if d.action == "start"]
        assert robot_starts, "the robot chose nothing"
        for decision in robot_starts:
            why = decision.why
            assert why is not None and why.mode is not None, decision
            assert why.mode.p_user == 0.5 and why.mode.mode == "hybrid"
            assert why.mode.draw is not None and why.mode.draw >= why.mode.p_user
            assert why.preferences is not None and len(why.preferences) == 3
            assert all(0 <= p.score <= 1 for p in why.preferences)
            scores = [p.score for p in why.preferences]
            assert scores == sorted(scores, reverse=True)
            assert why.motivation is not None and set(why.motivation.drives) >= {"rest"}
        menus = [d.decision for d in sim.decisions if d.decision.activity == "menu"]
        for decision in (d for d in menus if d.action == "start"):
            assert decision.why is not None and decision.why.mode is not None
            assert decision.why.mode.draw is not None
            assert decision.why.mode.draw < decision.why.mode.p_user  # type: ignore[operator]
        cancels = [d.decision for d in sim.decisions if d.decision.action == "cancel"]
        assert cancels and all(d.why and d.why.evidence == d.detail for d in cancels)


def test_a_rule_that_decides_is_named_with_its_file_and_line(tmp_path: Path) -> None:
    rules = (
        'component ChooseMode [ activate "autonomous" ]\n\n'
        "component ChooseEntertainment [\n"
        '  if params.user.id = "ann" then activate "bingo"\n'
        "]\n"
    )
    with _sim(tmp_path, rules) as sim:
        sim.presence = ANN
        sim.feed(keys.PERCEPTION_USER, ANN)
        sim.run_for(5)
        starts = [d.decision for d in sim.decisions if d.decision.action == "start"]
        bingo = next(d for d in starts if d.activity == "bingo")
        assert bingo.why is not None and bingo.why.rule is not None
        rule = bingo.why.rule
        assert rule.component == "ChooseEntertainment" and rule.activate == ["bingo"]
        assert rule.file == str(tmp_path / "decisions.dmsl") and rule.line == 4


def test_the_motivations_behavior_says_which_drive_dominates() -> None:
    with _sim() as sim:
        sim.run_for(2)
        start = next(d.decision for d in sim.decisions if d.decision.reason == "motivation")
        assert start.why is not None and start.why.motivation is not None
        assert start.why.motivation.drives
