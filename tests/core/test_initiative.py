"""Initiative from the user's own acts, requests served at once, and perception that
goes quiet is "unknown", not "gone".

Real controller stack on a virtual clock (real SQLite, the simulated Mini); the user is
scripted here, so that each test says exactly what the user does.
"""

from __future__ import annotations

import pytest

from dms.kernel import keys
from dms.kernel.messages import Request, Speech
from memory import proactivity
from sim.harness import Simulation
from tests.core.scripted import quiet_settings, seated


def _sim(**controller: object) -> Simulation:
    inputs = {"stale_after_s": {"perception/user": 5.0}}
    return seated(quiet_settings(dict(controller), inputs=inputs))


def _say(sim: Simulation, text: str) -> None:
    sim.feed(keys.PERCEPTION_SPEECH, Speech(text=text, confidence=0.95))
    sim.tick(urgent=True)


def _answer_menus(sim: Simulation, seconds: float, answer: str) -> int:
    """Run ``seconds``; say ``answer`` to every menu; the number of menus answered."""
    answered, end = 0, sim.t + seconds
    while sim.t < end:
        sim.run_for(1)
        current = sim.controller.current
        if (
            current is not None
            and current.name == "menu"
            and current.started != getattr(sim, "_answered_menu", None)
        ):
            sim._answered_menu = current.started  # type: ignore[attr-defined]
            _say(sim, answer)
            answered += 1
    return answered


def _profile(sim: Simulation) -> object:
    profiles = sim.controller.deps.profiles
    assert profiles is not None
    return profiles.store.get("ann")


# ------------------------------------------------------------------ the estimator


def test_declined_chances_make_a_low_estimate_and_taken_ones_a_high_one() -> None:
    assert proactivity.estimate(0, 12, None)[0] == "low"
    assert proactivity.estimate(12, 12, None)[0] == "high"
    assert proactivity.estimate(6, 12, None)[0] == "moderate"
    assert proactivity.estimate(0, 2, None)[0] == "unknown"


def test_the_answer_on_initiative_seeds_the_estimate() -> None:
    # "start conversations often" (robot initiative high): a user of little initiative
    assert proactivity.estimate(0, 0, "high")[0] == "low"
    assert proactivity.estimate(0, 0, "low")[0] == "high"
    # ... and the record overrides it
    assert proactivity.estimate(15, 16, "high")[0] == "high"


def test_hysteresis_keeps_the_level_near_a_cut() -> None:
    # mean (1 + 7) / (2 + 22) = 0.333...: just past the low/moderate cut
    assert proactivity.estimate(7, 22, None, previous="low") == proactivity.estimate(
        7, 22, None, previous="low"
    )
    assert proactivity.estimate(7, 22, None, previous="low")[0] == "low"
    assert proactivity.estimate(7, 22, None, previous="moderate")[0] == "moderate"
    assert proactivity.estimate(3, 22, None, previous="moderate")[0] == "low"


def test_the_record_is_recent() -> None:
    taken, offered = 40, 40  # a long history of taking the initiative
    for _ in range(60):  # then sixty chances let pass
        taken, offered = proactivity.forget(taken, offered + 1)
    assert offered <= 2 * proactivity.WINDOW + 1
    assert proactivity.estimate(taken, offered, None, previous="high")[0] == "low"


# ------------------------------------------------------------------ the controller


@pytest.mark.parametrize(("answer", "level"), [("you choose", "low"), ("bingo", "high")])
def test_what_the_user_does_with_menus_sets_their_proactivity(answer: str, level: str) -> None:
    with _sim(user_initiative={"unknown": 1.0, "moderate": 1.0, "low": 1.0, "high": 1.0}) as sim:
        answered = _answer_menus(sim, 3000, answer)  # long enough for five menus
        assert answered >= 5
        profile = _profile(sim)
        assert profile.proactivity == level, (answered, profile)  # type: ignore[attr-defined]
        assert profile.initiative_offered >= 5  # type: ignore[attr-defined]


def test_a_declined_menu_lets_the_robot_choose_next() -> None:
    with _sim(user_initiative={"unknown": 1.0}) as sim:
        _answer_menus(sim, 60, "you choose")
        picks = [d.decision for d in sim.decisions if d.decision.reason == "preference"]
        assert picks and picks[0].chosen_by == "robot"


def _cancel_counts(sim: Simulation, activity: str) -> int:
    profile = _profile(sim)
    score = profile.scores.get(activity)  # type: ignore[attr-defined]
    return 0 if score is None else int(score.cancellations)


@pytest.mark.parametrize(("by", "counts"), [("caregiver-app", False), ("ann", True)])
def test_only_the_users_own_cancel_counts_against_an_activity(by: str, counts: bool) -> None:
    with _sim(user_initiative={"unknown": 0.0}) as sim:
        sim.feed(keys.REQUEST, Request(action="start", activity="bingo", by="caregiver-app"))
        sim.tick(urgent=True)
        sim.run_for(5)
        assert sim.controller.current is not None and sim.controller.current.name == "bingo"
        before = _profile(sim)
        sim.feed(keys.REQUEST, Request(action="cancel", activity="bingo", by=by))
        sim.tick(urgent=True)
        sim.run_for(2)
        after = _profile(sim)
        assert _cancel_counts(sim, "bingo") == (1 if counts else 0)
        taken = after.initiative_taken - before.initiative_taken  # type: ignore[attr-defined]
        assert taken == 0, "a cancel is not a start; the start was the app's"


def test_a_request_during_the_opening_question_is_served_within_one_tick() -> None:
    with _sim(session_questions=4) as sim:
        sim.run_for(3)
        assert sim.controller.dialog is not None, "the opening question is open"
        mark = len(sim.decisions)
        sim.feed(keys.REQUEST, Request(action="start", activity="bingo", by="app"))
        record = sim.tick(urgent=True)
        started = [d for d in record.decisions if d.action == "start"]
        assert [d.activity for d in started] == ["bingo"], sim.decisions[mark:]
        assert sim.controller.dialog is None


def test_an_activity_asked_for_by_voice_during_a_question_wins() -> None:
    with _sim(session_questions=4) as sim:
        sim.run_for(3)
        assert sim.controller.dialog is not None
        _say(sim, "let's play bingo")
        assert sim.controller.current is not None and sim.controller.current.name == "bingo"


def test_requests_that_cannot_be_served_say_why() -> None:
    with _sim(session_questions=4) as sim:  # a question is open: nothing runs
        sim.run_for(3)
        for action in ("cancel", "pause", "resume"):
            sim.feed(keys.REQUEST, Request(action=action, by="app"))
        sim.tick(urgent=True)
        said = [e[2] for e in sim.errors if e[1] == keys.REQUEST]
        assert len(said) == 3 and all("no activity runs" in line for line in said), said


def test_stale_perception_keeps_the_activity_for_the_grace_and_then_ends_the_session() -> None:
    with _sim(user_initiative={"unknown": 0.0}) as sim:
        sim.feed(keys.REQUEST, Request(action="start", activity="bingo", by="app"))
        sim.tick(urgent=True)
        sim.perception_on = False  # the camera stops publishing
        quiet_at = sim.t
        sim.run_for(35)
        state = sim.last.state  # type: ignore[union-attr]
        assert state.inputs["perception/user"] == "stale"
        assert state.activity is not None and state.activity.name == "bingo"
        assert state.user is not None and state.user.id == "ann"
        assert not [d for d in sim.decisions if d.t > quiet_at and d.decision.action == "start"]
        sim.run_for(40)
        ends = [d.decision for d in sim.decisions if d.decision.reason == "input_missing"]
        assert ends and ends[0].action == "cancel" and ends[0].activity == "bingo"
        assert sim.last.state.user is None  # type: ignore[union-attr]


def test_a_cancel_in_the_same_tick_as_its_start_withdraws_the_start() -> None:
    with _sim(user_initiative={"unknown": 0.0}) as sim:
        sim.run_for(3)
        mark = len(sim.decisions)
        sim.feed(keys.REQUEST, Request(action="start", activity="bingo", by="app"))
        sim.feed(keys.REQUEST, Request(action="cancel", activity="bingo", by="app"))
        sim.tick(urgent=True)
        decided = [d.decision for d in sim.decisions[mark:]]
        assert not [d for d in decided if d.activity == "bingo"], decided
        assert not [e for e in sim.errors if e[1] == keys.REQUEST], sim.errors


def test_a_start_of_what_runs_then_its_cancel_in_one_tick_cancels_it() -> None:
    with _sim(user_initiative={"unknown": 0.0}) as sim:
        sim.run_for(3)
        sim.feed(keys.REQUEST, Request(action="start", activity="bingo", by="app"))
        sim.tick(urgent=True)
        assert (sim.decisions[-1].decision.action, sim.decisions[-1].decision.activity) == (
            "start",
            "bingo",
        )
        mark = len(sim.decisions)
        sim.feed(keys.REQUEST, Request(action="start", activity="bingo", by="app"))
        sim.feed(keys.REQUEST, Request(action="cancel", activity="bingo", by="app"))
        sim.tick(urgent=True)
        decided = [(d.decision.action, d.decision.activity) for d in sim.decisions[mark:]]
        assert decided[:1] == [("cancel", "bingo")], decided
        assert ("start", "bingo") not in decided, decided
