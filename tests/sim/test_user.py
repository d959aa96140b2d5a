"""The simulated user: answers what the robot asks, as its persona would."""

from __future__ import annotations

import random
from datetime import UTC, datetime, timedelta

from dms.kernel import keys
from dms.kernel.messages import Decision, RobotCommand, ScreenChoice, Speech, Touch
from sim.persona import Persona, Preferences, SpeechHabits
from sim.user import SimulatedUser

T0 = datetime(2026, 11, 23, 10, 0, tzinfo=UTC)


def _persona(**changes: object) -> Persona:
    base = Persona(
        name="tester",
        preferences=Preferences(quiz=0.9, bingo=0.1),
        speech=SpeechHabits(error_rate=0.0, no_answer_rate=0.0, screen_rate=0.0),
        arrive_after_s=1.0,  # type: ignore[arg-type]
        proactivity="high",  # picks from a menu itself, unless a test says otherwise
    )
    return base.model_copy(update=changes)


def _ready(user: SimulatedUser) -> datetime:
    user.arrive(T0)
    assert user.perception().present and not user.perception().ready
    out = user.due(T0 + timedelta(seconds=1))
    assert out and out[0][0] == keys.PERCEPTION_USER and user.perception().ready
    return T0 + timedelta(seconds=1)


def _say(text: str, n: int = 0) -> RobotCommand:
    return RobotCommand(id=f"c{n}", channel="speech", action="say", args={"text": text})


def _show(choices: list[str], n: int = 1) -> RobotCommand:
    return RobotCommand(
        id=f"s{n}", channel="screen", action="show", args={"text": "?", "choices": choices}
    )


def _decision(action: str, activity: str) -> Decision:
    return Decision(
        tick=1,
        time="2026-11-23T10:00:00.000Z",
        action=action,  # type: ignore[arg-type]
        activity=activity,
        manager="entertainment",
        reason="preference",
        chosen_by="robot",
    )


def _run(user: SimulatedUser, until: datetime) -> list[tuple[str, object]]:
    out: list[tuple[str, object]] = []
    while (due := user.next_due()) is not None and due <= until:
        out.extend(user.due(due))
    return out


def test_picks_the_liked_activity_from_a_menu() -> None:
    user = SimulatedUser(_persona(), random.Random(1))
    now = _ready(user)
    user.on_command(_say("What would you like to do?"), now)
    user.on_command(_show(["bingo", "quiz", "jokes"]), now)
    out = _run(user, now + timedelta(seconds=10))
    assert len(out) == 1
    key, message = out[0]
    assert key == keys.PERCEPTION_SPEECH and isinstance(message, Speech)
    assert message.text == "quiz"
    assert user.stats.menu_choices == 1


def test_answers_on_screen_when_it_prefers_to() -> None:
    persona = _persona(speech=SpeechHabits(error_rate=0.0, no_answer_rate=0.0, screen_rate=1.0))
    user = SimulatedUser(persona, random.Random(2))
    now = _ready(user)
    user.on_command(_say("How much did you like the quiz, from one to five?"), now)
    user.on_command(_show(["1", "2", "3", "4", "5"]), now)
    [(key, message)] = _run(user, now + timedelta(seconds=10))
    assert key == keys.PERCEPTION_SCREEN and isinstance(message, ScreenChoice)
    assert int(message.choice) >= 4  # it likes the quiz (0.9)


def test_misrecognized_answer_is_garbled_then_retried() -> None:
    persona = _persona(speech=SpeechHabits(error_rate=1.0, no_answer_rate=0.0, screen_rate=0.0))
    user = SimulatedUser(persona, random.Random(3))
    now = _ready(user)
    user.on_command(_say("How are you today?"), now)
    out = _run(user, now + timedelta(seconds=30))
    assert len(out) == 2  # the first try and one retry, both misheard
    assert all(isinstance(m, Speech) and m.confidence < 0.5 for _, m in out)
    assert user.stats.misrecognized == 2


def test_never_answers_when_it_does_not_answer() -> None:
    persona = _persona(speech=SpeechHabits(error_rate=0.0, no_answer_rate=1.0))
    user = SimulatedUser(persona, random.Random(4))
    now = _ready(user)
    user.on_command(_say("What is your name?"), now)
    assert _run(user, now + timedelta(seconds=60)) == []
    assert user.stats.unanswered == 1


def test_touches_the_shoulder_and_says_stop_in_a_disliked_activity() -> None:
    user = SimulatedUser(_persona(), random.Random(5))
    now = _ready(user)
    user.on_decision(_decision("start", "bingo"), now)
    out = _run(user, now + timedelta(seconds=120))
    assert [(k, m) for k, m in out] == [
        (keys.PERCEPTION_TOUCH, Touch(part="right_shoulder", kind="tap"))
    ]
    asked = now + timedelta(seconds=70)
    user.on_command(_say("Do you want to stop the bingo? Say stop or continue.", 9), asked)
    user.on_command(_show(["stop", "continue", "yes", "no"], 9), asked)
    [(_, answer)] = _run(user, asked + timedelta(seconds=10))
    assert isinstance(answer, Speech) and answer.text == "stop"


def test_does_not_touch_in_a_liked_activity_nor_after_it_ended() -> None:
    user = SimulatedUser(_persona(), random.Random(6))
    now = _ready(user)
    user.on_decision(_decision("start", "quiz"), now)
    assert _run(user, now + timedelta(seconds=300)) == []
    user.on_decision(_decision("start", "bingo"), now)
    user.on_decision(_decision("complete", "bingo"), now + timedelta(seconds=1))
    outputs = _run(user, now + timedelta(seconds=300))
    assert all(key != keys.PERCEPTION_TOUCH for key, _ in outputs)


def test_says_continue_when_it_did_not_ask_to_stop() -> None:
    user = SimulatedUser(_persona(), random.Random(7))
    now = _ready(user)
    user.on_decision(_decision("start", "quiz"), now)
    user.on_command(_say("Do you want to stop the quiz? Say stop or continue."), now)
    user.on_command(_show(["stop", "continue", "yes", "no"]), now)
    [(_, answer)] = _run(user, now + timedelta(seconds=10))
    assert isinstance(answer, Speech) and answer.text == "continue"


def test_leaving_forgets_pending_answers() -> None:
    user = SimulatedUser(_persona(), random.Random(8))
    now = _ready(user)
    user.on_command(_say("What is your name?"), now)
    user.leave(now)
    assert user.next_due() is None
    assert not user.perception().present
    user.on_command(_say("Are you there?"), now)  # nobody hears it
    assert user.next_due() is None


def test_choices_shown_before_the_question_is_spoken_still_count() -> None:
    # The arbiter serves each channel apart: the screen may show the choices before
    # the speech channel is free to say the question.
    user = SimulatedUser(_persona(), random.Random(9))
    now = _ready(user)
    user.on_command(_show(["bingo", "quiz"]), now)
    user.on_command(_say("What would you like to do?"), now + timedelta(seconds=0.5))
    [(_, answer)] = _run(user, now + timedelta(seconds=10))
    assert isinstance(answer, Speech) and answer.text == "quiz"
    assert user.stats.questions_heard == 1


def test_picks_an_activity_not_done_yet_this_visit() -> None:
    user = SimulatedUser(_persona(), random.Random(2))
    now = _ready(user)
    user.on_decision(_decision("start", "quiz"), now)
    user.on_decision(_decision("complete", "quiz"), now)
    user.on_command(_show(["quiz", "bingo", "talk"]), now)
    out = _run(user, now + timedelta(seconds=60))
    # quiz is the favourite but was done; talk is not what the participants came for
    assert [m.text for k, m in out if isinstance(m, Speech)] == ["bingo"]
    user.leave(now)
    now = _ready(user)  # a new visit: the favourite again
    user.on_command(_show(["quiz", "bingo"]), now)
    out = _run(user, now + timedelta(seconds=60))
    assert [m.text for k, m in out if isinstance(m, Speech)] == ["quiz"]


def test_stops_activities_the_less_often_the_better_liked() -> None:
    from sim.persona import Patience

    patience = Patience(dislike_below=0.2, bored_below=0.8, stop_after_s=5.0)  # type: ignore[arg-type]
    persona = _persona(
        patience=patience, preferences=Preferences(quiz=0.9, bingo=0.1, news=0.35, jokes=0.65)
    )
    assert persona.stop_chance("bingo") == 1.0 and persona.stop_chance("quiz") == 0.0
    assert persona.stop_chance("news") == 0.75 and round(persona.stop_chance("jokes"), 2) == 0.25
    touched = {"news": 0, "jokes": 0}
    for seed in range(200):
        for name in touched:
            user = SimulatedUser(persona, random.Random(seed))
            now = _ready(user)
            user.on_decision(_decision("start", name), now)
            out = _run(user, now + timedelta(seconds=10))
            touched[name] += any(isinstance(m, Touch) for _k, m in out)
    assert 120 <= touched["news"] <= 180 and 25 <= touched["jokes"] <= 75


def test_answers_yes_or_no_about_itself_truthfully() -> None:
    for lives_alone, expected in ((True, "yes"), (False, "no")):
        user = SimulatedUser(_persona(features={"lives_alone": lives_alone}), random.Random(0))
        now = _ready(user)
        user.on_command(_say("Do you live alone?"), now)
        user.on_command(_show(["yes", "no"]), now)
        out = _run(user, now + timedelta(seconds=30))
        assert [m.text for k, m in out if isinstance(m, Speech)] == [expected]


def test_answers_the_question_on_initiative_as_its_proactivity_has_it() -> None:
    wanted = {"low": "high", "moderate": "moderate", "high": "low"}
    for level, answer in wanted.items():
        for seed in range(5):
            user = SimulatedUser(_persona(proactivity=level), random.Random(seed))
            now = _ready(user)
            text = "How often should I start a conversation: low, moderate or high?"
            user.on_command(_say(text), now)
            user.on_command(_show(["low", "moderate", "high"]), now)
            [(_, message)] = _run(user, now + timedelta(seconds=10))
            assert isinstance(message, Speech) and message.text == answer, (level, seed)


def test_a_misheard_menu_answer_is_said_again_not_chosen_anew() -> None:
    habits = SpeechHabits(error_rate=1.0, no_answer_rate=0.0, screen_rate=0.0)
    for seed in range(40):
        user = SimulatedUser(_persona(proactivity="moderate", speech=habits), random.Random(seed))
        now = _ready(user)
        user.on_command(_say("What would you like to do?"), now)
        user.on_command(_show(["bingo", "quiz", "jokes"]), now)
        first, retry = (m for _, m in _run(user, now + timedelta(seconds=60)))
        assert isinstance(first, Speech) and isinstance(retry, Speech)
        # garbled word for word: "you choose" has two words, an activity one
        assert len(first.text.split()) == len(retry.text.split()), seed
        assert user.stats.menu_declines <= 1, seed


def test_a_moderate_user_declines_some_menus_a_high_one_none() -> None:
    def declines(level: str) -> int:
        count = 0
        for seed in range(40):
            user = SimulatedUser(_persona(proactivity=level), random.Random(seed))
            now = _ready(user)
            user.on_command(_say("What would you like to do?"), now)
            user.on_command(_show(["bingo", "quiz", "jokes"]), now)
            _run(user, now + timedelta(seconds=30))
            count += user.stats.menu_declines
        return count

    low, moderate, high = declines("low"), declines("moderate"), declines("high")
    assert high == 0 and 0 < moderate < low, (low, moderate, high)
