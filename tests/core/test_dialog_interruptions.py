"""Questions and menus the user does not simply answer: an activity asked for instead, a
menu left unanswered, a reminder that falls due while the robot waits for an answer.

Real controller stack on a virtual clock (real SQLite, the simulated Mini); the user is
scripted, so that each test says exactly what the user does.
"""

from __future__ import annotations

from datetime import datetime, timedelta

import pytest

from agenda import ItemSpec
from dms.dialog import Dialog, DialogKind, feedback_dialog
from dms.kernel import keys
from dms.kernel.messages import Decision, RobotCommand, ScreenChoice, Speech, Touch
from memory.questions import Question
from sim.harness import Simulation
from tests.core.scripted import quiet_settings, seated

MENU_FIRST = {"user_initiative": {"unknown": 1.0}}
"""The user always has the initiative: the robot opens the menu."""


def _sim(**controller: object) -> Simulation:
    return seated(quiet_settings(dict(controller)))


def _say(sim: Simulation, text: str) -> list[Decision]:
    sim.feed(keys.PERCEPTION_SPEECH, Speech(text=text, confidence=0.95))
    return list(sim.tick(urgent=True).decisions)


def _tap(sim: Simulation, choice: str) -> list[Decision]:
    sim.feed(keys.PERCEPTION_SCREEN, ScreenChoice(choice=choice))
    return list(sim.tick(urgent=True).decisions)


def _since(sim: Simulation, mark: int) -> list[Decision]:
    return [timed.decision for timed in sim.decisions[mark:]]


def _remind(sim: Simulation, in_s: float, **item: object) -> None:
    """An agenda item for Ann, due ``in_s`` from now (a reminder unless ``item`` says)."""
    agenda = sim.stack.agenda
    assert agenda is not None
    data: dict[str, object] = {"user_id": "ann", "kind": "reminder", "text": "Time for your pills."}
    data |= {"at": sim.now() + timedelta(seconds=in_s), **item}
    if data["kind"] == "event":
        data.pop("text")
    agenda.add(ItemSpec.from_data(data), sim.now())


def _run_until_decision(sim: Simulation, seconds: float, action: str, activity: str) -> float:
    """Run up to ``seconds`` until a decision ``action activity``; its time."""
    mark, end = len(sim.decisions), sim.t + seconds
    while sim.t < end:
        sim.run_for(0.5)
        for timed in sim.decisions[mark:]:
            if timed.decision.action == action and timed.decision.activity == activity:
                return timed.t
    raise AssertionError(f"no {action} {activity} in {seconds} s: {_since(sim, mark)}")


def _said(sim: Simulation) -> list[str]:
    """What the robot says from now on (filled as it says it)."""
    said: list[str] = []

    def keep(command: RobotCommand, _now: datetime) -> None:
        if command.channel == "speech" and command.action == "say":
            said.append(str(command.args.get("text", "")))

    sim.command_listeners.append(keep)
    return said


# ------------------------------------------------------------------ an activity instead


def test_a_screen_choice_of_an_activity_during_the_name_question_starts_it_at_once() -> None:
    with _sim(session_questions=4) as sim:
        sim.run_for(2)
        dialog = sim.controller.dialog
        assert dialog is not None and "name" in dialog.question.lower()
        decisions = _tap(sim, "bingo")
        started = [d for d in decisions if d.action == "start"]
        assert [(d.activity, d.reason, d.chosen_by) for d in started] == [
            ("bingo", "user_request", "user")
        ]
        assert sim.controller.dialog is None
        assert sim.controller.counters.unanswered == 0, "closed by the request, not unanswered"
        sim.run_for(2)
        profiles = sim.controller.deps.profiles
        assert profiles is not None
        assert getattr(profiles.store.get("ann"), "name", None) != "bingo"


@pytest.mark.parametrize("said", ["bingo", "Bingo!", "lottery"])
def test_a_bare_activity_name_said_to_the_name_question_asks_for_it(said: str) -> None:
    with _sim(session_questions=4) as sim:
        sim.run_for(2)
        dialog = sim.controller.dialog
        assert dialog is not None and "name" in dialog.question.lower()
        decisions = _say(sim, said)
        started = [(d.activity, d.reason, d.chosen_by) for d in decisions if d.action == "start"]
        assert started == [("bingo", "user_request", "user")]
        assert sim.controller.counters.unanswered == 0, "closed by the request, not unanswered"
        sim.run_for(2)
        profiles = sim.controller.deps.profiles
        assert profiles is not None
        assert getattr(profiles.store.get("ann"), "name", None) is None


def test_a_name_that_only_contains_an_activity_word_is_a_name() -> None:
    with _sim(session_questions=4) as sim:
        sim.run_for(2)
        decisions = _say(sim, "my name is Dance Smith")
        assert not [d for d in decisions if d.action == "start" and d.activity == "dance"]
        sim.run_for(2)
        profiles = sim.controller.deps.profiles
        assert profiles is not None
        assert getattr(profiles.store.get("ann"), "name", None) == "Dance Smith"


def test_an_activity_named_without_asking_for_it_answers_another_question() -> None:
    with _sim(session_questions=0, user_initiative={"unknown": 0.0}) as sim:
        sim.run_for(1)
        controller = sim.controller
        hobbies = Question("hobbies", "What are your hobbies?", None, "hobbies")
        controller.dialogs.ask_question(hobbies, sim.now())
        decisions = _say(sim, "bingo")  # a hobby, for all the robot knows
        assert not [d for d in decisions if d.action == "start" and d.activity == "bingo"]


def test_a_choice_the_question_itself_offers_is_its_answer() -> None:
    with _sim() as sim:
        sim.run_for(2)
        controller = sim.controller
        question = Dialog(
            DialogKind.GENERAL_QUESTION,
            "What do you like more?",
            ("news", "music"),
            sim.now() + timedelta(seconds=15),
        )
        controller.dialogs.open(question, sim.now())
        _tap(sim, "news")
        assert question.answer == "news"
        assert controller.current is None or controller.current.name != "news"


def test_asking_for_the_same_activity_again_during_its_feedback_question_starts_it() -> None:
    with _sim() as sim:
        sim.run_for(2)
        sim.controller.dialogs.open(feedback_dialog("quiz", sim.now(), 15), sim.now())
        decisions = _say(sim, "let's play the quiz again")
        started = [(d.activity, d.reason) for d in decisions if d.action == "start"]
        assert started == [("quiz", "user_request")]


def test_an_activity_asked_for_during_continue_or_stop_replaces_the_paused_one() -> None:
    with _sim(user_initiative={"unknown": 0.0}) as sim:
        sim.run_for(1)
        _say(sim, "let's play the quiz")
        sim.run_for(5)
        sim.feed(keys.PERCEPTION_TOUCH, Touch(part="right_shoulder", kind="tap"))
        sim.tick(urgent=True)
        dialog = sim.controller.dialog
        assert dialog is not None and dialog.kind is DialogKind.CONFIRM_CANCEL
        decisions = _tap(sim, "bingo")
        assert [(d.action, d.activity, d.reason) for d in decisions] == [
            ("cancel", "quiz", "user_request"),
            ("start", "bingo", "user_request"),
        ]
        assert sim.controller.dialog is None


def test_the_activity_continue_or_stop_is_about_asked_for_again_continues_it() -> None:
    with _sim(user_initiative={"unknown": 0.0}) as sim:
        sim.run_for(1)
        _say(sim, "let's play the quiz")
        sim.run_for(5)
        sim.feed(keys.PERCEPTION_TOUCH, Touch(part="right_shoulder", kind="tap"))
        sim.tick(urgent=True)
        decisions = _tap(sim, "quiz")
        assert sim.controller.dialog is not None, "about the quiz: not a request"
        assert not [d for d in decisions if d.action in ("cancel", "start")]


# ------------------------------------------------------------------ a menu left unanswered


def test_a_menu_nobody_answers_ends_as_unanswered_and_the_robot_chooses() -> None:
    with _sim(menu_timeout_s=30, **MENU_FIRST) as sim:
        sim.run_for(1)
        current = sim.controller.current
        assert current is not None and current.name == "menu"
        ended = _run_until_decision(sim, 60, "cancel", "menu")
        assert 30 <= ended <= 31.5
        assert sim.controller.counters.unanswered == 1
        sim.run_for(1)
        after = [d for d in _since(sim, 0) if d.action == "start" and d.activity != "menu"]
        assert after and after[0].chosen_by == "robot" and after[0].reason == "preference"
        session = sim.controller.sessions.session
        assert session is not None and session.account is not None
        counters = sim.controller.counters
        metrics = session.account.result(sim.now(), unanswered=counters.unanswered)
        assert metrics["user_not_answering"] == 1


def test_a_try_at_answering_the_menu_gives_it_its_time_again() -> None:
    with _sim(menu_timeout_s=30, **MENU_FIRST) as sim:
        sim.run_for(20)
        _say(sim, "hmm, let me see")  # heard, not a choice: the menu asks again
        ended = _run_until_decision(sim, 60, "cancel", "menu")
        assert 50 <= ended <= 51.5


# ------------------------------------------------------------------ a reminder in between


def test_a_reminder_due_during_the_menu_is_said_and_the_menu_offered_again() -> None:
    with _sim(**MENU_FIRST) as sim:
        said = _said(sim)
        sim.run_for(2)
        _remind(sim, 10)
        at = _run_until_decision(sim, 15, "start", "notification")
        assert at < 13.5, "said when due, not when the menu ends"
        again = _run_until_decision(sim, 15, "start", "menu")
        assert "Time for your pills." in said
        menus = [text for text in said if text.startswith("What would you like to do?")]
        assert again > at and len(menus) == 2, said
        decisions = _tap(sim, "quiz")
        sim.run_for(2)
        starts = [d for d in _since(sim, 0) if d.action == "start" and d.activity == "quiz"]
        assert starts and starts[0].chosen_by == "user", decisions


def test_a_menu_offered_again_after_a_reminder_keeps_the_time_of_its_first_offer() -> None:
    with _sim(menu_timeout_s=30, **MENU_FIRST) as sim:
        sim.run_for(1)
        first = next(t.t for t in sim.decisions if t.decision.activity == "menu")
        _remind(sim, 10)
        again = _run_until_decision(sim, 20, "start", "menu")
        assert again - first < 30
        ended = _run_until_decision(sim, 40, "cancel", "menu")
        assert ended - first <= 30.5, "never left longer than menu_timeout_s unanswered"
        assert sim.controller.counters.unanswered == 1


def test_a_menu_whose_time_ran_out_during_a_reminder_is_not_offered_again() -> None:
    long_text = " ".join(["Time for your pills, with a glass of water, then rest."] * 8)
    with _sim(menu_timeout_s=30, **MENU_FIRST) as sim:
        sim.run_for(1)
        first = next(t.t for t in sim.decisions if t.decision.activity == "menu")
        _remind(sim, 10, text=long_text)
        done = _run_until_decision(sim, 60, "complete", "notification")
        assert done - first > 30, "the reminder outlasts the menu's time"
        sim.run_for(1)
        after = [t.decision for t in sim.decisions if t.t >= done and t.decision.action == "start"]
        assert after and after[0].activity != "menu", after
        assert after[0].chosen_by == "robot" and after[0].why is not None
        assert after[0].why.mode is not None and after[0].why.mode.left_to_robot
        assert sim.controller.counters.unanswered == 1


def test_a_reminder_due_during_a_question_is_said_and_the_question_asked_again() -> None:
    with _sim(session_questions=1, question_timeout_s=15) as sim:
        said = _said(sim)
        sim.run_for(1)
        question = sim.controller.dialog
        assert question is not None
        _remind(sim, 3)
        _run_until_decision(sim, 5, "start", "notification")
        assert sim.controller.dialog is None
        _run_until_decision(sim, 15, "complete", "notification")
        assert sim.controller.dialog is question, "asked again after the reminder"
        assert said.count(question.question) == 2, said
        assert question.asked is not None
        assert question.deadline == question.asked + timedelta(seconds=15)
        _say(sim, "Ann")
        assert question.answer == "Ann" and sim.controller.dialog is None
        assert sim.controller.counters.unanswered == 0


def test_an_answer_given_while_the_reminder_is_said_is_kept() -> None:
    with _sim(session_questions=1) as sim:
        said = _said(sim)
        sim.run_for(1)
        question = sim.controller.dialog
        assert question is not None
        _remind(sim, 3)
        _run_until_decision(sim, 5, "start", "notification")
        _say(sim, "Ann")
        _run_until_decision(sim, 15, "complete", "notification")
        assert question.answer == "Ann"
        assert sim.controller.dialog is None and said.count(question.question) == 1


def test_a_reminder_during_continue_or_stop_keeps_the_activity_paused_until_the_answer() -> None:
    with _sim(user_initiative={"unknown": 0.0}) as sim:
        sim.run_for(1)
        _say(sim, "let's play the quiz")
        sim.run_for(5)
        sim.feed(keys.PERCEPTION_TOUCH, Touch(part="right_shoulder", kind="tap"))
        sim.tick(urgent=True)
        _remind(sim, 2)
        _run_until_decision(sim, 5, "start", "notification")
        suspended = sim.controller.suspended
        assert suspended is not None and suspended.name == "quiz" and suspended.paused
        _run_until_decision(sim, 15, "complete", "notification")
        dialog = sim.controller.dialog
        assert dialog is not None and dialog.kind is DialogKind.CONFIRM_CANCEL
        quiz = sim.controller.current
        assert quiz is not None and quiz.name == "quiz" and quiz.paused
        first = _say(sim, "stop")[0]
        assert (first.action, first.activity, first.reason) == ("cancel", "quiz", "confirm_cancel")


def test_a_high_priority_event_during_a_question_drops_it_and_starts() -> None:
    with _sim(session_questions=1) as sim:
        sim.run_for(1)
        assert sim.controller.dialog is not None
        _remind(sim, 3, kind="event", activity="cognitive_stimulation", priority="high")
        _run_until_decision(sim, 5, "start", "cognitive_stimulation")
        assert sim.controller.dialog is None and sim.controller.dialogs.held is None
        assert sim.controller.counters.unanswered == 0
