"""The sixteen shipped behaviors do what their names promise on the simulated robot."""

from __future__ import annotations

import pytest

from activities import Activity, ActivityStatus, BehaviorLibrary
from activities.containers import Concurrence, StateMachine
from dms.kernel.activity_names import ACTIVITIES, USER_SELECTABLE
from dms.kernel.messages import RobotCommand, ScreenChoice, Speech, Touch
from tests.activities.conftest import Bench, FakeRules


def _answer_everything(bench: Bench, name: str, args: dict[str, str] | None = None) -> Activity:
    """Run ``name``, answering each question with its first choice (or a sentence)."""
    activity = bench.start(bench.create(name, args))
    answered = 0
    for _ in range(2 * 3600):
        if activity.finished:
            break
        bench.advance(activity, 0.5)
        asks = [c for c in bench.commands if c.channel == "speech" and "?" in c.args["text"]]
        if len(asks) > answered:
            answered = len(asks)
            screens = [c for c in bench.commands if c.channel == "screen" and c.args.get("choices")]
            text = screens[-1].args["choices"][0] if screens else "I like gardening"
            activity.deliver(Speech(text=str(text), confidence=0.9))
    return activity


def test_the_library_has_the_sixteen_activities(shipped: BehaviorLibrary) -> None:
    assert shipped.names == frozenset(ACTIVITIES)


@pytest.mark.parametrize("name", sorted(set(ACTIVITIES) - {"sleep", "wait"}))
def test_every_shipped_behavior_runs_to_an_outcome(shipped: BehaviorLibrary, name: str) -> None:
    bench = Bench(shipped, seed=3)
    activity = _answer_everything(bench, name, {"text": "Your doctor at five."})
    assert activity.status is ActivityStatus.COMPLETED, activity.result
    assert activity.result.outcome in shipped.spec(name).outcomes
    assert activity.result.error is None
    assert bench.said(), f"{name} said nothing"
    assert all(c.id.startswith("cmd-") for c in bench.commands)
    assert len({c.id for c in bench.commands}) == len(bench.commands)


@pytest.mark.parametrize("name", sorted(set(ACTIVITIES) - {"sleep", "wait"}))
def test_shipped_behaviors_complete_in_plausible_time(shipped: BehaviorLibrary, name: str) -> None:
    bench = Bench(shipped, seed=5)
    activity = bench.start(bench.create(name, {"text": "Your doctor at five."}))
    start = bench.now
    status = bench.finish(activity, limit_s=1800)  # nobody answers: timeouts end the questions
    assert status is ActivityStatus.COMPLETED, activity.result
    seconds = (bench.now - start).total_seconds()
    assert seconds < 1200  # the quiz's 25 questions, each asked twice, unanswered
    if name not in ("notification", "menu"):
        assert seconds >= 20, f"{name} lasted only {seconds} s"


@pytest.mark.parametrize("name", ["sleep", "wait"])
def test_sleep_and_wait_run_until_cancelled(bench: Bench, name: str) -> None:
    activity = bench.start(bench.create(name))
    bench.advance(activity, 3600, step=5)
    assert activity.status is ActivityStatus.RUNNING
    activity.cancel(bench.now)
    assert activity.tick(bench.now) is ActivityStatus.CANCELLED


def test_sleep_shows_closed_eyes_and_dim_leds(bench: Bench) -> None:
    activity = bench.start(bench.create("sleep"))
    bench.advance(activity, 10)
    assert bench.robot.screen.get("face") == "closed_eyes"
    assert bench.robot.leds.get("pattern") == "breathing"


def test_quiz_checks_the_answers(bench: Bench) -> None:
    activity = bench.start(bench.create("quiz"))
    for _ in range(25):
        bench.run_until(activity, lambda: activity.state_path.endswith("ASK"))
        question = activity.userdata["question"]
        assert len(question["choices"]) == 4
        assert question["answer"] in question["choices"]
        assert activity.deliver(Speech(text=str(question["answer"]), confidence=0.9))
        bench.run_until(activity, lambda: not activity.state_path.endswith("ASK"))
    assert bench.finish(activity) is ActivityStatus.COMPLETED
    assert activity.result.data["score"] == 25
    assert "25 right out of 25" in bench.said()[-1]


def test_quiz_shoulder_guard_ends_the_game_with_the_score(bench: Bench) -> None:
    activity = bench.start(bench.create("quiz"))
    bench.run_until(activity, lambda: activity.state_path.endswith("ASK"))
    assert activity.deliver(Touch(part="left_shoulder", kind="tap"))
    bench.advance(activity, 0.5)
    assert activity.state_path == "RESULT"
    assert bench.finish(activity) is ActivityStatus.COMPLETED
    assert "0 right out of 1" in bench.said()[-1]


def test_bingo_calls_numbers_and_checks_the_card(bench: Bench) -> None:
    activity = bench.start(bench.create("bingo"))
    bench.run_until(activity, lambda: "card" in activity.userdata)
    card = activity.userdata["card"]
    assert len(card) == 9 and all(1 <= n <= 60 for n in card)
    bench.run_until(activity, lambda: activity.state_path.endswith("LISTEN"))
    assert activity.deliver(Speech(text="bingo!", confidence=0.9))  # too early
    bench.run_until(activity, lambda: "Not yet" in bench.last_said(), limit_s=30)
    assert bench.finish(activity) is ActivityStatus.COMPLETED
    called = activity.result.data["called"]
    assert set(card) <= set(called)
    assert bench.said()[-1].startswith("Bingo!")
    numbers = [
        c.args["text"] for c in bench.commands if c.args.get("text", "").startswith("Number")
    ]
    assert len(numbers) == len(called) and len(set(numbers)) == len(numbers)


def test_bingo_is_guarded_by_the_shoulder(bench: Bench) -> None:
    activity = bench.start(bench.create("bingo"))
    bench.run_until(activity, lambda: activity.state_path.startswith("GAME"))
    assert activity.deliver(Touch(part="left_shoulder", kind="tap"))
    bench.finish(activity)
    assert "stop the bingo" in bench.said()[-1]


def test_dance_is_music_and_motion_together_until_the_music_ends(bench: Bench) -> None:
    activity = bench.start(bench.create("dance"))
    bench.run_until(activity, lambda: activity.state_path.startswith("DANCE"))
    root = activity.root
    assert isinstance(root, StateMachine)
    dance = root.states["DANCE"]
    assert isinstance(dance, Concurrence)
    bench.advance(activity, 10)
    assert bench.expression.active("media") is not None
    assert bench.expression.active("motion") is not None
    bench.run_until(activity, lambda: not activity.state_path.startswith("DANCE"))
    assert dance.outcome == "done"
    media = [c for c in bench.commands if c.channel == "media"]
    assert len(media) == 1 and 220 <= media[0].args["duration_s"] <= 330  # a whole song
    assert bench.expression.active("motion") is None or bench.finish(activity)


def test_news_and_weather_read_the_local_content(bench: Bench) -> None:
    bench.finish(bench.start(bench.create("news")))
    assert sum("." in text for text in bench.said()) >= 6
    bench.finish(bench.start(bench.create("weather")))
    assert any("degrees" in text and "tomorrow" in text for text in bench.said())


def test_cognitive_stimulation_iterates_over_exercises(bench: Bench) -> None:
    activity = bench.start(bench.create("cognitive_stimulation"))
    seen = set()
    while not activity.finished:
        bench.run_until(activity, lambda: activity.finished or activity.state_path.endswith("ASK"))
        if activity.finished:
            break
        exercise = activity.userdata["exercise"]
        seen.add(exercise["skill"])
        activity.deliver(ScreenChoice(choice=exercise["answer"]))
        bench.run_until(activity, lambda: not activity.state_path.endswith("ASK"))
    assert len(seen) == 5
    assert activity.result.data["score"] == 5


def test_talk_chooses_topics_through_the_decision_state(bench: Bench) -> None:
    bench.rules = FakeRules({"TalkTopic": ["hobbies"]})
    activity = bench.start(bench.create("talk"))
    for _ in range(3):
        bench.run_until(activity, lambda: activity.state_path.endswith("HOBBIES"))
        activity.deliver(Speech(text="painting", confidence=0.9))
        bench.run_until(activity, lambda: not activity.state_path.endswith("HOBBIES"))
    bench.finish(activity)
    assert bench.rules.asked.count("TalkTopic") == 3
    assert bench.stored == {"hobby": "painting"}


def test_talk_has_a_built_in_default_without_rules(bench: Bench) -> None:
    bench.finish(bench.start(bench.create("talk")), limit_s=600)
    questions = [t for t in bench.said() if "?" in t]
    assert len(questions) == 3


@pytest.mark.parametrize(
    ("event", "expected"),
    [
        (Speech(text="let's play the quiz", confidence=0.9), "quiz"),
        (Speech(text="tell me a joke", confidence=0.9), "jokes"),
        (ScreenChoice(choice="cognitive_stimulation"), "cognitive_stimulation"),
        (ScreenChoice(choice="weather"), "weather"),
    ],
)
def test_menu_returns_the_choice_as_redirect(
    bench: Bench, event: Speech | ScreenChoice, expected: str
) -> None:
    activity = bench.start(bench.create("menu"))
    shown = [c for c in bench.commands if c.channel == "screen"][-1]
    assert shown.args["choices"] == list(USER_SELECTABLE)
    assert activity.deliver(event)
    assert bench.finish(activity) is ActivityStatus.COMPLETED
    assert activity.result.redirect == expected
    assert activity.result.outcome == "chosen"


def test_menu_without_an_answer_has_no_redirect(bench: Bench) -> None:
    activity = bench.start(bench.create("menu"))
    bench.finish(activity)
    assert activity.result.outcome == "no_choice"
    assert activity.result.redirect is None


def test_notification_preempts_speech_and_the_interrupted_sentence_is_repeated(
    bench: Bench,
) -> None:
    quiz = bench.start(bench.create("quiz"))
    intro = bench.expression.active("speech")
    assert intro is not None and intro.source == "activity:quiz"
    note = bench.start(bench.create("notification", {"text": "Time for your pills."}))
    bench.run_until(note, lambda: bench.last_said() == "Time for your pills.", limit_s=5)
    assert intro.status.value == "queued"  # preempted, waiting to be repeated
    assert bench.finish(note) is ActivityStatus.COMPLETED
    bench.advance(quiz, 1)
    assert bench.last_said().startswith("Let's play a quiz")
    assert intro.sends == 2
    bench.run_until(quiz, lambda: quiz.state_path.endswith("ASK"))


def test_paused_activity_resumes_its_sentence_after_a_notification(bench: Bench) -> None:
    quiz = bench.start(bench.create("quiz"))
    quiz.pause(bench.now)
    note = bench.start(bench.create("notification", {"text": "Time for your pills."}))
    assert bench.finish(note) is ActivityStatus.COMPLETED
    assert "Time for your pills." in bench.said()
    quiz.resume(bench.now)
    assert bench.last_said().startswith("Let's play a quiz")


def test_jokes_tells_twenty_jokes(bench: Bench) -> None:
    activity = bench.start(bench.create("jokes"))
    bench.finish(activity)
    assert len(activity.result.data["jokes"]) == 20
    assert len(bench.said()) == 2 + 20 * 2


def test_the_voice_volume_comes_from_the_voice_settings_rule(bench: Bench) -> None:
    bench.rules = FakeRules({"VoiceSettings": ["loud"]})
    activity = bench.start(bench.create("presentation"))
    bench.advance(activity, 5)
    speech: list[RobotCommand] = [c for c in bench.commands if c.channel == "speech"]
    assert speech[0].args["volume"] == 80
    assert "Ana" in speech[0].args["text"]


def test_the_speaking_rate_comes_from_the_voice_settings_rule_and_slows_the_robot(
    bench: Bench,
) -> None:
    bench.rules = FakeRules({"VoiceSettings": ["volume:35", "rate:75"]})
    activity = bench.start(bench.create("presentation"))
    bench.advance(activity, 5)
    speech: list[RobotCommand] = [c for c in bench.commands if c.channel == "speech"]
    assert speech[0].args["volume"] == 35 and speech[0].args["rate_wpm"] == 75
    slow = bench.robot.duration(speech[0])
    assert slow > bench.robot.duration(speech[0].model_copy(update={"args": {"text": "x"}}))
    normal = speech[0].model_copy(update={"args": {"text": speech[0].args["text"]}})
    assert slow == pytest.approx(0.3 + (bench.robot.duration(normal) - 0.3) * 2.0)


@pytest.mark.parametrize("style", ["voice", "screen"])
def test_a_quiz_question_points_a_screen_user_to_the_screen(bench: Bench, style: str) -> None:
    bench.user["interaction_style"] = style
    activity = bench.start(bench.create("quiz"))
    bench.advance(activity, 20)
    questions = [
        c.args["text"] for c in bench.commands if c.channel == "speech" and "?" in c.args["text"]
    ]
    assert questions
    hinted = questions[0].endswith("Please answer on the screen.")
    assert hinted is (style == "screen")
