"""The controller's decision points with real DMSL rules, on the simulator's virtual clock.

Each test writes a rules file and a scenario that names it, runs the whole controller
stack (sim.runner) and checks what the robot decided and why (``Decision.detail``).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from sim.harness import TimedDecision
from sim.runner import ScenarioResult, run_scenario

SETTINGS = {"controller": {"session_questions": 0, "feedback_probability": 0}}


def _run(tmp_path: Path, rules: str, timeline: list[str], duration_s: float) -> ScenarioResult:
    """Run a scenario whose daemon loads ``rules``; fail on any error the stack reports."""
    rules_file = tmp_path / "decisions.dmsl"
    rules_file.write_text(rules, encoding="utf-8")
    settings = {**SETTINGS, "rules": {"files": [str(rules_file)]}}
    scenario = tmp_path / "scenario.yaml"
    scenario.write_text(
        f"name: rules\nseed: 5\nduration_s: {duration_s}\nsettings: {json.dumps(settings)}\n"
        "timeline:\n" + "".join(f"  - {step}\n" for step in timeline),
        encoding="utf-8",
    )
    result = run_scenario(scenario)
    assert [e for e in result.errors if e[1] == "rules"] == []
    return result


def quiz_decisions(result: ScenarioResult) -> list[TimedDecision]:
    return [d for d in result.decisions if d.decision.activity == "quiz"]


def _starts(result: ScenarioResult) -> list[TimedDecision]:
    return [d for d in result.decisions if d.decision.action == "start"]


@pytest.mark.parametrize(
    ("user", "mode", "first"),
    [("alice", "user_choice", "menu"), ("bob", "autonomous", "weather")],
)
def test_choose_mode_picks_the_mode_for_the_user(
    tmp_path: Path, user: str, mode: str, first: str
) -> None:
    rules = """\
component ChooseMode [
    if params.user.id = "alice" then activate "user_choice" else activate "autonomous"
]
component ChooseEntertainment [ activate "weather" ]
"""
    result = _run(tmp_path, rules, [f"{{at: 0, arrive: {{user: {user}}}}}"], 60)
    picks = [d.decision for d in _starts(result) if d.decision.reason != "motivation"]
    assert picks, [d.decision for d in result.decisions]
    assert picks[0].activity == first
    expected = f"rule ChooseMode -> {mode}" if mode == "user_choice" else None
    if expected is not None:
        assert picks[0].chosen_by == "user" and picks[0].detail == expected
    else:  # autonomous: the robot picks, through ChooseEntertainment
        assert picks[0].chosen_by == "robot"
        assert picks[0].detail == "rule ChooseEntertainment -> weather"


def test_choose_entertainment_picks_the_activity_from_user_parameters(tmp_path: Path) -> None:
    rules = """\
component ChooseMode [ activate "autonomous" ]
component ChooseEntertainment [
    if params.user.id = "bob" then activate "jokes" else activate "news"
]
"""
    result = _run(tmp_path, rules, ["{at: 0, arrive: {user: bob}}"], 60)
    picks = [d.decision for d in _starts(result) if d.decision.reason == "preference"]
    assert picks and picks[0].activity == "jokes" and picks[0].chosen_by == "robot"
    assert picks[0].detail == "rule ChooseEntertainment -> jokes"


QUIZ_WITH_REMINDER = [
    "{at: 0, arrive: {user: alice}}",
    "{at: 2, request: {action: start, activity: quiz, by: caregiver}}",
    '{at: 3, agenda: {kind: reminder, user: alice, in_s: 27, text: "Time for your pills."}}',
]


@pytest.mark.parametrize("answer", ["deny", "allow"])
def test_allow_interruption_false_keeps_a_reminder_from_pausing_the_quiz(
    tmp_path: Path, answer: str
) -> None:
    rules = f"""\
component AllowInterruption [
    if params.user.id = "alice" then activate "{answer}"
]
"""
    result = _run(tmp_path, rules, QUIZ_WITH_REMINDER, 45)
    quiz = [d for d in _starts(result) if d.decision.activity == "quiz"]
    assert quiz and 2 <= quiz[0].t <= 3
    pauses = [d for d in result.decisions if d.decision.action == "pause"]
    notified = [d for d in _starts(result) if d.decision.activity == "notification"]
    if answer == "deny":
        assert pauses == [] and notified == []  # the reminder waits for the quiz to end
        assert not any(d.decision.action == "cancel" for d in quiz_decisions(result))
    else:  # the contrast: the same reminder pauses the quiz when the rule allows it
        assert [p.decision.activity for p in pauses] == ["quiz"]
        assert pauses[0].decision.reason == "agenda" and 30 <= pauses[0].t <= 31
        assert notified and notified[0].t <= 31


@pytest.mark.parametrize(("activity", "paused"), [("cognitive_stimulation", False), ("quiz", True)])
def test_the_shipped_rule_keeps_reminders_out_of_cognitive_stimulation(
    tmp_path: Path, activity: str, paused: bool
) -> None:
    """``params.robot.currenttask`` is the running activity, so the example rule works."""
    shipped = Path(__file__).resolve().parents[2] / "dms/rules/examples/decisions.dmsl"
    timeline = [
        "{at: 0, arrive: {user: alice}}",
        f"{{at: 2, request: {{action: start, activity: {activity}, by: caregiver}}}}",
        '{at: 3, agenda: {kind: reminder, user: alice, in_s: 27, text: "Pills."}}',
    ]
    result = _run(tmp_path, shipped.read_text(encoding="utf-8"), timeline, 45)
    started = [d for d in _starts(result) if d.decision.activity == activity]
    assert started and 2 <= started[0].t <= 3
    pauses = [d.decision.activity for d in result.decisions if d.decision.action == "pause"]
    assert pauses == ([activity] if paused else [])
