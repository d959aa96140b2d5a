"""Scenario files, visit planning and Table 4 arithmetic, without running the stack."""

from __future__ import annotations

import itertools
import random
from pathlib import Path

import pytest

from dms.messages import Decision
from sim.errors import SpecError
from sim.harness import TimedDecision
from sim.longterm import plan_visits
from sim.persona import load_persona, shipped_personas
from sim.scenario import load_scenario, shipped_scenarios
from sim.study import SessionObserver, StudyResult


def test_every_shipped_scenario_is_valid() -> None:
    paths = shipped_scenarios()
    assert len(paths) >= 10
    for path in paths:
        loaded = load_scenario(path)
        assert loaded.scenario.expect, f"{path.name} asserts nothing"


@pytest.mark.parametrize(
    ("text", "line", "field"),
    [
        ("name: s\ntimeline:\n  - {at: 1, say: hi, tap: quiz}\n", 3, "timeline.0"),
        ("name: s\ntimeline:\n  - at: 1\n    touch: {part: knee}\n", 4, "timeline.0.touch.part"),
        (
            "name: s\ntimeline:\n  - {at: 1, request: {action: start, activity: golf}}\n",
            3,
            "timeline.0.request.activity",
        ),
        ("name: s\nexpect:\n  - {state: {field: mode, equals: hybrid}}\n", 3, "expect.0"),
        ("name: s\nexpect:\n  - decision: {action: jump}\n", 3, "expect.0.decision.action"),
        (
            "name: s\nsettings:\n  controller: {feedback_probability: 3}\n",
            3,
            "settings.controller.feedback_probability",
        ),
        ("name: s\nduration_s: -1\n", 2, "duration_s"),
    ],
)
def test_bad_scenario_names_file_line_and_field(
    tmp_path: Path, text: str, line: int, field: str
) -> None:
    path = tmp_path / "s.yaml"
    path.write_text(text)
    with pytest.raises(SpecError) as caught:
        load_scenario(path)
    assert str(caught.value).startswith(f"{path}:{line}: {field}"), str(caught.value)


def test_step_after_the_end_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "s.yaml"
    path.write_text("name: s\nduration_s: 10\ntimeline:\n  - {at: 20, leave: true}\n")
    with pytest.raises(SpecError, match=r":4: timeline.0.at: 20 s is after duration_s 10"):
        load_scenario(path)


def test_visits_never_overlap_and_follow_the_schedules() -> None:
    personas = [load_persona(name) for name in shipped_personas() if name != "demo"][:3]
    visits = plan_visits(personas, 14, random.Random(1))
    assert visits == sorted(visits, key=lambda v: v.start_s)
    for before, after in itertools.pairwise(visits):
        assert after.start_s >= before.end_s
    per_user = [sum(1 for v in visits if v.user == i) for i in range(3)]
    # alice: daily + twice a week; bernard: 4 days a week; carmen: daily.
    assert per_user == [14 + 4, 8, 14]
    assert all(0 <= v.start_s < v.end_s <= 14 * 86400 for v in visits)


def _d(
    action: str,
    activity: str | None,
    reason: str,
    chosen_by: str | None = None,
    detail: str | None = None,
) -> Decision:
    return Decision.model_validate(
        {
            "tick": 1,
            "time": "2026-11-23T10:00:00.000Z",
            "action": action,
            "activity": activity,
            "manager": None,
            "reason": reason,
            "chosen_by": chosen_by,
            "detail": detail,
        }
    )


def test_session_observer_measures_table_4() -> None:
    observer = SessionObserver()
    feed = [
        (1.0, _d("ask", None, "general_question")),
        (10.0, _d("start", "menu", "user_choice", "user")),
        (14.0, _d("start", "quiz", "user_choice", "user")),
        (200.0, _d("cancel", "quiz", "confirm_cancel", "user")),
        (230.0, _d("start", "jokes", "preference", "robot")),
        (400.0, _d("complete", "jokes", "completed", "robot")),
        (420.0, _d("fail", "bingo", "activity_error", "robot", "not loaded: broken")),
    ]
    for t, decision in feed:
        if decision.activity == "jokes":
            observer.on_command(None, None, t)  # type: ignore[arg-type]
        observer.on_decision(TimedDecision(t, decision))
        if decision.action == "start" and decision.activity != "jokes":
            observer.on_command(None, None, t + 0.5)  # type: ignore[arg-type]
    m = observer.metrics
    assert (m.questions, m.activities, m.robot_decisions, m.user_selections) == (1, 2, 1, 1)
    assert m.cancels == 1 and m.not_loaded == 1 and m.other_failures == 0
    assert m.activity_times == [186.0, 170.0]
    assert m.change_times == [30.0]
    assert m.load_times == [0.5, 0.0]
    result = StudyResult([m, m], 1.0, 30.0, "moderate", 0)
    summary = result.to_json()
    assert summary["activities_per_session"] == 2.0
    assert summary["failures"]["activity_not_loaded"] == 2
    assert "Activities per session" in result.table()
