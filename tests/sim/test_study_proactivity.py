"""``--proactivity`` sets the participants' true proactivity, and the initiative follows.

A low-proactivity participant leaves the menu's choice to the robot; a high one picks,
and asks for favourites by name. The daemon is not told which: it asks (the general
question on initiative, among the opening questions, before the first choice) and
watches what they do. Low gives at least twice as many robot decisions as user
selections, high the reverse, from the first visit on.
"""

from __future__ import annotations

from sim.study import run_study, study_settings


def test_low_proactivity_lets_the_robot_choose() -> None:
    result = run_study(8, 30.0, "low", 1, study_settings())
    robot = sum(s.robot_decisions for s in result.sessions)
    user = sum(s.user_selections for s in result.sessions)
    assert robot >= 2 * user, (robot, user)


def test_high_proactivity_takes_the_initiative_once_known() -> None:
    result = run_study(6, 30.0, "high", 1, study_settings(), repeat=3)
    later = [s for s in result.sessions if s.visit >= 2]
    robot = sum(s.robot_decisions for s in later)
    user = sum(s.user_selections for s in later)
    assert user >= 2 * robot, (robot, user)
    first = [s for s in result.sessions if s.visit == 1]
    assert sum(s.user_selections for s in later) > sum(s.user_selections for s in first)


def _split(level: str, sessions: int) -> tuple[int, int]:
    result = run_study(sessions, 30.0, level, 1, study_settings())  # type: ignore[arg-type]
    robot = sum(s.robot_decisions for s in result.sessions)
    user = sum(s.user_selections for s in result.sessions)
    return robot, user


def test_high_proactivity_takes_the_initiative_from_the_first_visit() -> None:
    robot, user = _split("high", 10)
    assert user >= 2 * robot, (robot, user)


def test_the_question_on_initiative_comes_before_the_first_choice() -> None:
    result = run_study(3, 5.0, "moderate", 2, study_settings(), record_decisions=True)
    for session in (1, 2, 3):
        decisions = [row.decision for row in result.decisions if row.session == session]
        asked = [d.detail or "" for d in decisions if d.reason == "general_question"]
        first_choice = next(
            i
            for i, d in enumerate(decisions)
            if d.action == "start" and d.chosen_by in ("robot", "user")
        )
        before = [d.detail or "" for d in decisions[:first_choice]]
        assert any("How often should I start" in text for text in asked[:2]), asked
        assert any("How often should I start" in text for text in before), before
