"""The controller's own dialogs ask in the user's interaction style (Table 2)."""

from __future__ import annotations

from datetime import UTC, datetime

from dms.config import Settings
from dms.dialog import Dialog, DialogKind, confirm_dialog, feedback_dialog
from dms.kernel import keys
from dms.kernel.expression import ExpressionArbiter
from dms.kernel.messages import RobotCommand, Touch, UserPerception
from sim.harness import Simulation
from sim.robot import SimRobot

T0 = datetime(2026, 11, 23, 10, 0, tzinfo=UTC)


def _asked(dialog: Dialog, style: str) -> list[RobotCommand]:
    sent: list[RobotCommand] = []
    dialog.ask(ExpressionArbiter(SimRobot(), sent.append), T0, style)
    return sent


def test_voice_reads_the_choices_and_screen_points_to_the_screen() -> None:
    question = Dialog(DialogKind.GENERAL_QUESTION, "Do you live alone?", ("yes", "no"), T0)
    voice, screen = _asked(question, "voice"), _asked(question, "screen")
    assert voice[0].args["text"] == "Do you live alone? You can say yes or no."
    assert screen[0].args["text"] == "Do you live alone? Please answer on the screen."
    for sent in (voice, screen):  # the buttons are there either way
        assert sent[1].channel == "screen" and sent[1].args["choices"] == ["yes", "no"]


def test_a_question_that_names_its_choices_is_not_repeated() -> None:
    confirm = confirm_dialog("quiz", T0, 10.0)
    assert _asked(confirm, "voice")[0].args["text"] == confirm.question
    rating = feedback_dialog("quiz", T0, 10.0)
    assert _asked(rating, "voice")[0].args["text"].endswith("You can say 1, 2, 3, 4 or 5.")


def test_an_open_question_is_spoken_in_either_style() -> None:
    open_question = Dialog(DialogKind.GENERAL_QUESTION, "What is your name?", (), T0)
    for style in ("voice", "screen"):
        sent = _asked(open_question, style)
        assert [c.channel for c in sent] == ["speech"]
        assert sent[0].args["text"] == "What is your name?"


def test_three_unanswered_voice_prompts_switch_the_user_to_the_screen() -> None:
    settings = Settings(controller={"session_questions": 3, "question_every": 0})
    said: list[str] = []

    def on_command(command: RobotCommand, _now: datetime) -> None:
        if command.channel == "speech":
            said.append(str(command.args.get("text", "")))

    with Simulation(settings, seed=2, start=T0) as sim:
        sim.command_listeners.append(on_command)
        sim.presence = UserPerception(present=True, user_id="zoe", ready=True, engagement=0.6)
        sim.feed(keys.PERCEPTION_USER, sim.presence)
        sim.run_for(3 * 15.0 + 10.0)  # three general questions that nobody answers
        store = sim.stack.store
        assert store is not None
        assert store.get("zoe").interaction_style == "screen"
        running = sim.controller.current
        assert running is not None and running.chosen_by != "motivation"
        sim.feed(keys.PERCEPTION_TOUCH, Touch(part="right_shoulder", kind="tap"))
        sim.tick(urgent=True)
    assert said[-1] == confirm_dialog(running.name, T0, 10.0).question.replace(
        "Say stop or continue.", "Say stop or continue. Please answer on the screen."
    )
