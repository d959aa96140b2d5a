"""Expression arbitration and the simulated Mini."""

from __future__ import annotations

from datetime import timedelta

import pytest

from activities import ActivityStatus, BehaviorLibrary
from dms.kernel.expression import CommandStatus, ExpressionArbiter, Priority
from dms.kernel.messages import RobotCommand
from sim.robot import SimRobot
from tests.activities.conftest import T0, Bench

WORDS_30 = " ".join(["word"] * 30)  # 12.3 s at 150 words per minute


def _arbiter(timeout: float = 5.0) -> tuple[SimRobot, ExpressionArbiter, list[RobotCommand]]:
    robot = SimRobot()
    sent: list[RobotCommand] = []
    return robot, ExpressionArbiter(robot, sent.append, ack_timeout_s=timeout), sent


def _run(arbiter: ExpressionArbiter, until: float, step: float = 0.5) -> None:
    t = 0.0
    while t < until:
        t += step
        arbiter.update(T0 + timedelta(seconds=t))


def test_commands_of_several_sources_never_collide_on_a_channel() -> None:
    robot, arbiter, sent = _arbiter()
    a = arbiter.request("activity:a", "speech", "say", {"text": WORDS_30}, T0)
    b = arbiter.request("activity:b", "speech", "say", {"text": "short one"}, T0)
    screen = arbiter.request("activity:b", "screen", "show", {"text": "x"}, T0)
    assert [c.channel for c in sent] == ["speech", "screen"]  # other channels go at once
    assert b.status is CommandStatus.QUEUED
    busy_speech = 0
    t = 0.0
    while not (a.finished and b.finished):
        t += 0.5
        arbiter.update(T0 + timedelta(seconds=t))
        busy_speech = max(busy_speech, sum(c.channel == "speech" for c in robot.busy))
    assert busy_speech == 1
    assert a.status is b.status is screen.status is CommandStatus.DONE
    assert 12.0 <= t <= 16.0
    assert len({c.id for c in sent}) == len(sent) == 3


def test_high_priority_speech_preempts_and_the_interrupted_one_is_repeated() -> None:
    _robot, arbiter, sent = _arbiter()
    story = arbiter.request("activity:quiz", "speech", "say", {"text": WORDS_30}, T0)
    _run(arbiter, 2)
    note = arbiter.request(
        "activity:notification",
        "speech",
        "say",
        {"text": "pills"},
        T0 + timedelta(seconds=2),
        priority=Priority.HIGH,
    )
    assert (note.status, story.status) == (CommandStatus.SENT, CommandStatus.QUEUED)
    assert arbiter.preemptions == 1
    _run(arbiter, 30)
    assert (note.status, story.status) == (CommandStatus.DONE, CommandStatus.DONE)
    texts = [c.args["text"] for c in sent]
    assert texts == [WORDS_30, "pills", WORDS_30]
    assert story.sends == 2 and sent[0].id != sent[2].id


def test_interrupt_source_withdraws_running_and_queued_commands() -> None:
    _robot, arbiter, sent = _arbiter()
    first = arbiter.request("dms", "speech", "say", {"text": WORDS_30}, T0)
    second = arbiter.request("dms", "speech", "say", {"text": "again"}, T0)
    other = arbiter.request("activity:x", "speech", "say", {"text": "mine"}, T0)
    arbiter.interrupt_source("dms", T0 + timedelta(seconds=1))
    assert first.status is second.status is CommandStatus.INTERRUPTED
    assert other.status is CommandStatus.SENT  # the channel went to the next source
    assert [c.args["text"] for c in sent] == [WORDS_30, "mine"]


def test_a_command_never_acknowledged_times_out() -> None:
    robot, arbiter, _sent = _arbiter(timeout=3.0)
    robot.set_fault("motion", "hang")
    wave = arbiter.request("a", "motion", "gesture", {"name": "wave"}, T0)
    nod = arbiter.request("a", "motion", "gesture", {"name": "nod"}, T0)
    _run(arbiter, 2.5)
    assert wave.status.value == "sent"
    _run(arbiter, 3.5)
    assert wave.status.value == "timed_out" and arbiter.timeouts == 1
    assert nod.status in (CommandStatus.SENT, CommandStatus.TIMED_OUT)  # the channel moved on
    robot.set_fault("motion", None)
    ok = arbiter.request("a", "motion", "gesture", {"name": "nod"}, T0 + timedelta(seconds=10))
    _run(arbiter, 20)
    assert ok.status is CommandStatus.DONE


def test_a_command_started_but_never_done_times_out_after_its_length() -> None:
    robot = SimRobot()
    arbiter = ExpressionArbiter(robot, lambda _c: None, ack_timeout_s=3.0, done_timeout_s=20.0)
    robot.set_fault("media", "stall")
    song = arbiter.request("a", "media", "play", {"file": "x.mp3", "duration_s": 30}, T0)
    _run(arbiter, 1)
    assert song.status is CommandStatus.STARTED
    _run(arbiter, 49)
    assert song.status is CommandStatus.STARTED  # 30 s of song plus 20 s of grace
    _run(arbiter, 51)
    assert song.status is CommandStatus.TIMED_OUT and "not done within 50 s" in (song.detail or "")
    assert arbiter.timeouts == 1 and robot.log[-1][1].action == "play"


def test_a_gesture_started_but_never_done_times_out() -> None:
    robot = SimRobot()
    arbiter = ExpressionArbiter(robot, lambda _c: None, ack_timeout_s=3.0, done_timeout_s=20.0)
    robot.set_fault("motion", "stall")
    wave = arbiter.request("a", "motion", "gesture", {"name": "wave"}, T0)
    _run(arbiter, 19.5)
    assert wave.status is CommandStatus.STARTED
    _run(arbiter, 21)
    assert wave.status is CommandStatus.TIMED_OUT and arbiter.timeouts == 1


def test_an_activity_fails_cleanly_when_the_robot_never_answers(shipped: BehaviorLibrary) -> None:
    bench = Bench(shipped)
    bench.robot.set_fault("speech", "hang")
    activity = bench.start(bench.create("jokes"))
    assert bench.finish(activity, limit_s=30) is ActivityStatus.FAILED
    assert activity.result.error is not None
    assert "timed_out" in activity.result.error and "INTRO" in activity.result.error
    assert bench.expression.pending("activity:jokes") == []


def test_an_activity_fails_when_the_robot_reports_failure(shipped: BehaviorLibrary) -> None:
    bench = Bench(shipped)
    bench.robot.set_fault("*", "fail")
    activity = bench.start(bench.create("dance"))
    assert bench.finish(activity, limit_s=10) is ActivityStatus.FAILED
    assert "failed" in (activity.result.error or "")


@pytest.mark.parametrize(
    ("channel", "args", "low", "high"),
    [
        ("speech", {"text": WORDS_30}, 12.0, 12.6),
        ("media", {"title": "x", "duration_s": 95}, 95, 95),
        ("motion", {"name": "wave"}, 2.5, 2.5),
        ("motion", {"name": "unknown_move"}, 2.0, 2.0),
        ("screen", {"text": "x"}, 0, 0),
        ("led", {"color": "red"}, 0, 0),
    ],
)
def test_sim_robot_durations(
    channel: str, args: dict[str, object], low: float, high: float
) -> None:
    robot = SimRobot(speaking_rate_wpm=150)
    command = RobotCommand.model_validate(
        {"id": "c1", "channel": channel, "action": "x", "args": args}
    )
    assert low <= robot.duration(command) <= high
    robot.send(command, T0)
    assert [f.status for f in robot.poll(T0)] == ["started"] + (["done"] if high == 0 else [])
    if high:
        took = robot.duration(command)
        assert robot.poll(T0 + timedelta(seconds=took - 0.01)) == []
        assert [f.status for f in robot.poll(T0 + timedelta(seconds=took))] == ["done"]


def test_sim_robot_interrupts_and_speaking_rate() -> None:
    slow = SimRobot(speaking_rate_wpm=60)
    command = RobotCommand(id="s", channel="speech", action="say", args={"text": "one two three"})
    assert slow.duration(command) == pytest.approx(3.3)
    slow.send(command, T0)
    slow.interrupt("s", T0 + timedelta(seconds=1))
    assert [f.status for f in slow.poll(T0 + timedelta(seconds=10))] == ["started", "interrupted"]
    with pytest.raises(ValueError):
        SimRobot(speaking_rate_wpm=0)
