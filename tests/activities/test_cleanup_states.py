"""Stopping an activity from outside the SMACH way: ``Activity.preempt`` and the
managers' ``cancel(cleanup_s=...)`` let the shipped behaviors' cleanup states run.

A person expects a game stopped midway to be closed, not cut: the quiz gives the
score, bingo and the exercises say they stop, the dance puts its lights back."""

from __future__ import annotations

from datetime import timedelta
from typing import Any

import pytest

from activities import Activity, ActivityStatus, BehaviorLibrary
from dms.kernel.activity_names import ManagerName
from managers.base import Manager, ManagerStatus
from managers.groups import make_managers
from tests.activities.conftest import Bench


def _preempt_when(bench: Bench, activity: Activity, path_part: str) -> None:
    bench.run_until(activity, lambda: path_part in activity.state_path)
    activity.preempt(bench.now, limit_s=30)


def test_a_quiz_stopped_mid_question_says_so_with_the_score(bench: Bench) -> None:
    activity = bench.start(bench.create("quiz"))
    _preempt_when(bench, activity, "ASK")
    assert activity.stopping and activity.state_path == "STOPPING"
    assert "let's stop the quiz here" in bench.last_said().lower()
    assert "0 right out of 1" in bench.last_said()
    assert bench.finish(activity, limit_s=30) is ActivityStatus.CANCELLED
    assert activity.result.outcome == "preempted"
    assert not activity.stopping


@pytest.mark.parametrize(
    ("name", "path_end", "words"),
    [
        ("bingo", "LISTEN", "stop the bingo"),
        ("cognitive_stimulation", "ASK", "stop the exercises"),
    ],
)
def test_games_stopped_midway_say_they_stop(
    bench: Bench, name: str, path_end: str, words: str
) -> None:
    activity = bench.start(bench.create(name))
    _preempt_when(bench, activity, path_end)
    assert words in bench.last_said()
    assert bench.finish(activity, limit_s=30) is ActivityStatus.CANCELLED
    assert activity.result.outcome == "preempted"


def test_a_dance_stopped_midway_puts_its_lights_back(bench: Bench) -> None:
    activity = bench.start(bench.create("dance"))
    _preempt_when(bench, activity, "MUSIC,MOVES/STEP")
    assert activity.state_path == "STOPPING"
    assert bench.finish(activity, limit_s=30) is ActivityStatus.CANCELLED
    leds = [c for c in bench.commands if c.channel == "led"]
    assert leds[-1].args.get("color") == "white" and leds[-1].args.get("pattern") == "solid"
    assert bench.expression.active("media") is None and bench.expression.active("motion") is None


def test_a_behavior_without_cleanup_ends_in_the_same_tick(bench: Bench) -> None:
    activity = bench.start(bench.create("jokes"))
    bench.advance(activity, 2)
    assert activity.preempt(bench.now, limit_s=30) is ActivityStatus.CANCELLED
    assert activity.result.outcome == "preempted" and not activity.stopping


def test_a_paused_quiz_goes_straight_to_its_cleanup_without_asking_again(
    bench: Bench,
) -> None:
    """The shoulder's "stop?" dialog pauses the quiz; "stop" cancels it from there."""
    activity = bench.start(bench.create("quiz"))
    bench.run_until(activity, lambda: activity.state_path.endswith("ASK"))
    question = bench.last_said()
    activity.pause(bench.now)
    said = len(bench.said())
    activity.preempt(bench.now, limit_s=30)
    assert activity.state_path == "STOPPING"
    assert bench.said()[said:] and "stop the quiz here" in bench.said()[said]
    assert question not in bench.said()[said:], "the question is not asked again"
    assert bench.finish(activity, limit_s=30) is ActivityStatus.CANCELLED


def test_an_unstarted_activity_is_cancelled(bench: Bench) -> None:
    activity = bench.create("quiz")
    assert activity.preempt(bench.now, limit_s=30) is ActivityStatus.CANCELLED
    assert not bench.said()


def test_asking_twice_is_one_request(bench: Bench) -> None:
    activity = bench.start(bench.create("quiz"))
    _preempt_when(bench, activity, "ASK")
    stopping = len(bench.said())
    activity.preempt(bench.now, limit_s=30)
    assert activity.state_path == "STOPPING" and len(bench.said()) == stopping


def test_a_cleanup_that_overruns_its_limit_is_cut_off(make: Any) -> None:
    bench = make(
        {
            "slow": """
            name: slow
            outcomes: [done, preempted]
            states:
              WORK:
                wait: {seconds: 100}
                transitions: {done: done, preempted: TIDY}
              TIDY:
                wait: {seconds: 100}
                transitions: {done: preempted}
            """
        }
    )
    activity = bench.start(bench.create("slow"))
    bench.advance(activity, 1)
    asked = bench.now
    activity.preempt(bench.now, limit_s=5)
    assert activity.state_path == "TIDY"
    bench.finish(activity, limit_s=30)
    assert activity.status is ActivityStatus.CANCELLED
    assert activity.result.outcome == "cancelled"
    assert timedelta(seconds=5) <= bench.now - asked <= timedelta(seconds=6)


def _quiz_asking(shipped: BehaviorLibrary) -> tuple[Bench, Manager, Activity]:
    """The entertainment manager running a quiz that is asking its first question."""
    bench = Bench(shipped)
    manager = make_managers(shipped)[ManagerName.ENTERTAINMENT]
    assert manager.start("quiz", bench.context("quiz"), bench.now).status is ManagerStatus.RUNNING
    quiz = manager.activity
    assert quiz is not None
    bench.run_until(quiz, lambda: quiz.state_path.endswith("ASK"))
    return bench, manager, quiz


def test_a_manager_is_free_at_once_while_the_old_activity_cleans_up(
    shipped: BehaviorLibrary,
) -> None:
    bench, manager, quiz = _quiz_asking(shipped)
    reply = manager.cancel(bench.now, cleanup_s=10)
    assert reply.status is ManagerStatus.CANCELLED and manager.activity is None
    assert manager.winding_down == (quiz,)
    started = manager.start("bingo", bench.context("bingo"), bench.now)
    assert started.status is ManagerStatus.RUNNING
    while manager.winding_down:
        bench.now += timedelta(seconds=0.5)
        bench.expression.update(bench.now)
        manager.wind_down(bench.now)
        manager.tick(bench.now)
    said = bench.said()
    stop = next(i for i, t in enumerate(said) if "stop the quiz" in t)
    bingo = next(i for i, t in enumerate(said) if t.startswith("Let's play bingo"))
    assert stop < bingo, "the next activity's speech waits for the cleanup's sentence"
    assert quiz.status is ActivityStatus.CANCELLED


def test_starting_the_same_activity_again_cuts_its_cleanup(shipped: BehaviorLibrary) -> None:
    bench, manager, old = _quiz_asking(shipped)
    manager.cancel(bench.now, cleanup_s=10)
    manager.start("quiz", bench.context("quiz"), bench.now)
    assert old.status is ActivityStatus.CANCELLED and manager.winding_down == ()


def test_shutdown_cuts_every_cleanup(shipped: BehaviorLibrary) -> None:
    bench, manager, quiz = _quiz_asking(shipped)
    manager.cancel(bench.now, cleanup_s=10)
    manager.stop_winding_down(bench.now)
    assert manager.winding_down == () and quiz.status is ActivityStatus.CANCELLED
    assert quiz.result.outcome == "cancelled"
