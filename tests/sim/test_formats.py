"""Scenario files, visit planning and Table 4 arithmetic, without running the stack."""

from __future__ import annotations

import itertools
import random
from datetime import UTC, datetime
from pathlib import Path

import pytest

from dms.kernel.expression import CommandHandle, CommandStatus, Priority
from dms.kernel.messages import Decision
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


START = datetime(2026, 11, 23, 10, 0, tzinfo=UTC)


def _handle(source: str) -> CommandHandle:
    return CommandHandle(source, "speech", "say", {"text": "hi"}, Priority.NORMAL)


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
    quiz = _handle("activity:quiz")
    jokes = _handle("activity:jokes")
    for t, decision in feed:
        if decision.activity == "jokes" and decision.action == "start":
            observer.on_command(jokes, t)  # sent in the tick that started it
        observer.on_decision(TimedDecision(t, decision))
        observer.on_tick(t)
        if decision.activity == "quiz" and decision.action == "start":
            observer.on_command(_handle("dialog"), t + 0.5)  # not the quiz's: ignored
            observer.on_tick(t + 0.5)
            observer.on_command(quiz, t + 3.0)  # its channel was busy until then
            observer.on_tick(t + 3.0)
            quiz.started_at = START
            observer.on_tick(t + 3.5)
        if decision.activity == "jokes" and decision.action == "start":
            jokes.started_at = START
            observer.on_tick(t + 0.5)
    m = observer.metrics
    assert (m.questions, m.activities, m.robot_decisions, m.user_selections) == (1, 2, 1, 1)
    assert m.cancels == 1 and m.not_loaded == 1 and m.other_failures == 0
    assert m.activity_times == [186.0, 170.0]
    assert m.change_times == [30.0]
    assert m.load_times == [3.5, 0.5]
    result = StudyResult([m, m], 1.0, 30.0, "moderate", 0)
    summary = result.to_json()
    assert summary["activities_per_session"] == 2.0
    assert summary["failures"]["activity_not_loaded"] == 2
    assert "Activities per session" in result.table()


def test_an_activity_whose_first_command_never_starts_has_no_load_time() -> None:
    observer = SessionObserver()
    handle = _handle("activity:dance")
    observer.on_decision(TimedDecision(5.0, _d("start", "dance", "preference", "robot")))
    observer.on_command(handle, 5.0)
    handle.status = CommandStatus.FAILED
    observer.on_tick(5.5)
    observer.on_decision(TimedDecision(6.0, _d("start", "jokes", "preference", "robot")))
    observer.on_decision(TimedDecision(8.0, _d("cancel", "jokes", "user_request", "user")))
    observer.on_tick(8.0)  # cancelled before any command: not loaded, not waited for
    assert observer.metrics.load_times == []
    assert observer.metrics.activities == 2


def test_the_stop_request_to_the_next_start_is_measured_beside_the_change_time() -> None:
    """The paper's 43.12 s row both ways: from an activity's end, and from the request."""
    observer = SessionObserver()
    feed = [
        (10.0, _d("start", "quiz", "user_choice", "user")),
        (100.0, _d("pause", "quiz", "confirm_cancel", "user")),  # the shoulder touched
        (108.0, _d("cancel", "quiz", "confirm_cancel", "user")),  # "stop"
        (140.0, _d("start", "jokes", "preference", "robot")),
        (150.0, _d("pause", "jokes", "confirm_cancel", "user")),
        (155.0, _d("resume", "jokes", "confirm_cancel", "user")),  # "continue": no stop
        (300.0, _d("complete", "jokes", "completed", "robot")),
        (330.0, _d("start", "bingo", "user_choice", "user")),
        (400.0, _d("cancel", "bingo", "user_request", "user")),  # "stop" in words
        (420.0, _d("start", "news", "user_choice", "user")),
    ]
    for t, decision in feed:
        observer.on_decision(TimedDecision(t, decision))
    m = observer.metrics
    assert m.change_times == [32.0, 30.0, 20.0]
    assert m.stop_times == [40.0, 20.0]
    result = StudyResult([m], 1.0, 30.0, "moderate", 0)
    assert result.to_json()["outcomes"]["stop_to_start_s"] == 30.0
