"""Every decision explains itself: ``Decision.why``."""

from __future__ import annotations

from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from dms.config import Settings
from dms.kernel import keys
from dms.kernel.activity_names import ENTERTAINMENT_ACTIVITIES
from dms.kernel.messages import Decision, ModeWhy, Request, Speech, UserPerception, Why
from memory import ActivityChooser, Profile
from sim.adapters import seed_profile
from sim.baselines import install
from sim.harness import Simulation
from sim.longterm import run_longterm

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
        assert cancels and all(
            d.why and d.detail and d.detail in (d.why.evidence or "") for d in cancels
        )


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


# ---------------------------------------------------------------- what drew the choice


def _robot_choices(decisions: list[Decision]) -> list[Decision]:
    return [
        d
        for d in decisions
        if d.chosen_by == "robot" and d.reason == "preference" and d.action == "start"
    ]


def _unexplained(decision: Decision) -> str | None:
    """Why the ``why`` of a robot choice does not explain its activity; None if it does."""
    why = decision.why
    if why is None:
        return "no why"
    if why.rule is not None:
        return None if decision.activity in why.rule.activate else "not the rule's"
    listed = [p.activity for p in why.preferences or []]
    choice = why.choice
    if choice is None:
        return None if decision.activity in listed else "no draw named"
    novelty = choice.novelty
    if choice.by == "novelty":
        if novelty is None or not novelty.draw < novelty.probability:
            return "novelty without its coin under the threshold"
        return None if decision.activity in novelty.untried else "novelty of a tried activity"
    if choice.by == "ranking":
        ranking = choice.ranking or []
        if sorted(ranking) != sorted(choice.candidates):
            return "the ranking is not of the candidates"
        scores = dict(listed_scores(decision))
        ranked = [scores[name] for name in ranking if name in scores]
        if ranked != sorted(ranked, reverse=True):
            return "the ranking disagrees with the predicted scores"
        return None if ranking and decision.activity == ranking[0] else "not the ranking's first"
    if choice.by == "sampling":
        if novelty is not None and novelty.draw < novelty.probability:
            return "sampling although the novelty coin won"
        samples = choice.samples or {}
        if set(samples) != set(choice.candidates):
            return "samples are not the candidates'"
        best = max(samples.values())
        return None if samples.get(str(decision.activity)) == best else "not the best sample"
    return None if decision.activity in choice.candidates else "not a candidate"


def test_every_robot_choice_of_a_seeded_run_is_its_rankings_best() -> None:
    """The paper's choice, by default: the best of the predicted ranking not just done."""
    result = run_longterm(days=3, users=3, seed=0)
    choices = _robot_choices([row.decision for row in result.decision_rows])
    assert len(choices) >= 10
    problems = [(d.activity, _unexplained(d)) for d in choices if _unexplained(d)]
    assert problems == []
    assert {d.why.choice.by for d in choices if d.why and d.why.choice} == {"ranking"}
    for decision in choices:
        assert decision.why is not None and decision.why.choice is not None
        if decision.why.choice.excluded:  # never the last activity twice in a row
            assert decision.activity not in decision.why.choice.excluded


def test_every_exploring_choice_of_a_seeded_run_is_explained_by_its_draw() -> None:
    settings = Settings.model_validate({"controller": {"chooser": "explore"}})
    result = run_longterm(days=3, users=3, seed=0, settings=settings)
    choices = _robot_choices([row.decision for row in result.decision_rows])
    assert len(choices) >= 10
    problems = [(d.activity, _unexplained(d)) for d in choices if _unexplained(d)]
    assert problems == []
    outside = [d for d in choices if d.activity not in [a for a, _ in _listed(d)]]
    assert outside, "the run should hold choices outside the top three, explained by a draw"
    assert {d.why.choice.by for d in choices if d.why and d.why.choice} == {"novelty", "sampling"}
    for decision in choices:
        assert decision.why is not None and decision.why.choice is not None
        if decision.why.choice.excluded:  # never the last activity twice in a row
            assert decision.activity not in decision.why.choice.excluded


def test_the_why_names_the_baseline_chooser_that_picked() -> None:
    with _sim() as sim:
        install(sim, "fixed", lambda _user: None, 0)
        sim.presence = ANN
        sim.feed(keys.PERCEPTION_USER, ANN)
        for _ in range(6):
            sim.run_for(20)
            sim.feed(keys.REQUEST, Request(action="cancel", by="app"))
            sim.tick(urgent=True)
        choices = _robot_choices([d.decision for d in sim.decisions])
        assert choices
        for decision in choices:
            assert decision.why is not None and decision.why.choice is not None
            assert decision.why.choice.by == "chooser", decision.why.choice
            assert decision.activity in decision.why.choice.candidates


def test_without_memory_the_why_says_the_pick_was_uniform() -> None:
    settings = Settings.model_validate({"controller": {"session_questions": 0}})
    with Simulation(settings, seed=6, start=START, with_memory=False) as sim:
        sim.presence = ANN
        sim.feed(keys.PERCEPTION_USER, ANN)
        for _ in range(6):
            sim.run_for(20)
            sim.feed(keys.REQUEST, Request(action="cancel", by="app"))
            sim.tick(urgent=True)
        choices = _robot_choices([d.decision for d in sim.decisions])
        assert choices
        for decision in choices:
            assert decision.why is not None and decision.why.choice is not None
            assert decision.why.choice.by == "random"
            assert decision.why.preferences is None
            assert decision.activity in decision.why.choice.candidates


def test_a_choice_left_to_the_robot_says_no_coin_was_tossed() -> None:
    settings = Settings.model_validate(
        {
            "controller": {
                "session_questions": 0,
                "menu_timeout_s": 5.0,
                "user_initiative": {"high": 1.0, "moderate": 1.0, "low": 1.0, "unknown": 1.0},
            },
            "inputs": {"stale_after_s": {"perception/user": 30.0}},
        }
    )
    with Simulation(settings, seed=6, start=START) as sim:
        sim.presence = ANN
        sim.feed(keys.PERCEPTION_USER, ANN)
        sim.run_for(10)  # the menu goes unanswered: the robot chooses
        starts = [d.decision for d in sim.decisions if d.decision.action == "start"]
        menu = next(d for d in starts if d.activity == "menu")
        assert menu.why is not None and menu.why.mode is not None
        assert menu.why.mode.draw is not None and menu.why.mode.draw < 1.0
        assert menu.why.mode.left_to_robot is None
        robot = _robot_choices(starts)[0]
        assert robot.why is not None and robot.why.mode is not None
        assert robot.why.mode.draw is None and robot.why.mode.left_to_robot is True


def test_the_new_why_fields_are_left_out_of_the_json_while_unset() -> None:
    assert Why(mode=ModeWhy(p_user=0.5, draw=0.7, mode="hybrid")).model_dump() == {
        "mode": {"p_user": 0.5, "draw": 0.7, "mode": "hybrid"},
        "preferences": None,
        "motivation": None,
        "rule": None,
        "evidence": None,
    }


# ---------------------------------------------------------------- the profile at the decision

AGE_QUESTION = {"name": "Ann", "robot_initiative_frequency": "low", "sex": "female"}
"""What Ann has told before: the next general question is her age."""


def _age_sim(tmp: Path, questions: int = 1) -> Simulation:
    """``questions`` general questions (the last one her age), then the robot's own
    choice (ChooseMode)."""
    path = tmp / "decisions.dmsl"
    path.write_text('component ChooseMode [ activate "autonomous" ]\n')
    data = {
        "controller": {
            "session_questions": questions,
            "question_every": 0,
            "feedback_probability": 0,
        },
        "inputs": {"stale_after_s": {"perception/user": 30.0}},
        "rules": {"files": [str(path)]},
    }
    return Simulation(Settings.model_validate(data), seed=6, start=START)


def _top_three(chooser: ActivityChooser, profile: Profile) -> list[tuple[str, float]]:
    means = {n: a / (a + b) for n, (a, b) in chooser.beliefs(profile).items()}
    top = sorted(ENTERTAINMENT_ACTIVITIES, key=lambda n: -means[n])[:3]
    return [(n, round(means[n], 3)) for n in top]


def _answer_age_then_choose(sim: Simulation, presence: UserPerception) -> Decision:
    """Ann answers the age question; the robot chooses in that same tick."""
    sim.presence = presence
    sim.feed(keys.PERCEPTION_USER, presence)
    sim.run_for(3)
    asked = [d.decision for d in sim.decisions if d.decision.action == "ask"]
    assert [d.detail for d in asked] == ["How old are you?"]
    sim.feed(keys.PERCEPTION_SPEECH, Speech(text="I am 85", confidence=0.95))
    record = sim.tick(urgent=True)
    choices = _robot_choices(list(record.decisions))
    assert len(choices) == 1, record.decisions
    return choices[0]


def listed_scores(decision: Decision) -> list[tuple[str, float]]:
    return [(p.activity, p.score) for p in (decision.why.preferences or [])] if decision.why else []


def _listed(decision: Decision) -> list[tuple[str, float]]:
    assert decision.why is not None and decision.why.preferences is not None
    return [(p.activity, p.score) for p in decision.why.preferences]


def test_an_answer_of_the_same_tick_counts_in_the_choice_and_its_why(tmp_path: Path) -> None:
    with _age_sim(tmp_path) as sim:
        seed_profile(sim.stack, "ann", AGE_QUESTION, START)
        before = sim.stack.store.get("ann")  # type: ignore[union-attr]
        choice = _answer_age_then_choose(sim, ANN)
        after = sim.stack.store.get("ann")  # type: ignore[union-attr]
        chooser = sim.controller.deps.chooser
        assert chooser is not None and after.age == 85 and before.age is None
        assert _listed(choice) == _top_three(chooser, after)
        assert _listed(choice) != _top_three(chooser, before)  # the age changes them


def test_an_answer_still_on_its_way_to_the_store_counts_in_the_choice(tmp_path: Path) -> None:
    """The daemon writes off the tick: the cached profile has not the answer yet."""
    with _age_sim(tmp_path) as sim:
        seed_profile(sim.stack, "ann", AGE_QUESTION, START)
        profiles = sim.controller.deps.profiles
        assert profiles is not None
        record_answer, in_flight = profiles.record_answer, []

        def late(*args: Any) -> None:  # held back: the answer is still on its way
            in_flight.append(args)

        profiles.record_answer = late  # type: ignore[method-assign]
        choice = _answer_age_then_choose(sim, ANN)
        cached = profiles.cached("ann")
        assert in_flight and cached is not None and cached.age is None
        chooser = sim.controller.deps.chooser
        assert chooser is not None
        assert _listed(choice) == _top_three(chooser, cached.model_copy(update={"age": 85}))
        profiles.record_answer = record_answer  # type: ignore[method-assign]
        for args in in_flight:
            record_answer(*args)  # the write lands
        assert sim.controller.sessions.profile() is profiles.cached("ann")


def test_a_newcomers_answers_count_before_she_is_stored(tmp_path: Path) -> None:
    """A user not stored yet goes on with an empty profile and held writes: her answers
    still count in the choices of her session."""
    unengaged = ANN.model_copy(update={"engagement": 0.0})  # never qualifies to be stored
    answers = {
        "What is your name?": "Ann",
        "How often should I start a conversation: low, moderate or high?": "low",
        "What is your gender?": "female",
        "How old are you?": "I am 85",
    }
    with _age_sim(tmp_path, questions=len(answers)) as sim:
        sim.presence = unengaged
        sim.feed(keys.PERCEPTION_USER, unengaged)
        choices: list[Decision] = []
        for _ in answers:
            sim.run_for(1)
            asked = [d.decision for d in sim.decisions if d.decision.action == "ask"][-1]
            sim.feed(keys.PERCEPTION_SPEECH, Speech(text=answers[str(asked.detail)], confidence=1))
            choices = _robot_choices(list(sim.tick(urgent=True).decisions))
        assert len(choices) == 1  # in the tick of the last answer
        session = sim.controller.sessions.session
        assert session is not None and session.newcomer is not None and session.held
        profile = sim.controller.sessions.profile()
        assert profile is not None and profile.age == 85 and profile.sex is not None
        chooser = sim.controller.deps.chooser
        assert chooser is not None
        assert _listed(choices[0]) == _top_three(chooser, profile)
        assert _listed(choices[0]) != _top_three(chooser, session.newcomer)
