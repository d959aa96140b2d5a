"""A wall clock set back or forward (by an administrator, by NTP after a long outage)
changes no decision: the drives and the robot commands' timeouts run on the monotonic
clock; dialogs, the menu, the new-user wait, activities and the simulated robot on the
steady time (the wall time with its steps taken out); and the step is reported once.

The clocks are fakes in this process (:class:`VirtualClock` with its wall clock
stepped), never the machine's.
"""

from __future__ import annotations

import textwrap
from collections.abc import Iterator
from datetime import UTC, datetime, timedelta
from pathlib import Path

import numpy as np
import pytest

from activities import Activity, ActivityContext, ActivityStatus, BehaviorLibrary
from dms.config import Settings, load_config
from dms.controller.drives import Drives
from dms.daemon import Daemon
from dms.dialog import DialogKind
from dms.inputs import InputSnapshot
from dms.kernel import keys
from dms.kernel.clock import SteadyTime, VirtualClock, WallSteps, describe_step
from dms.kernel.expression import CommandStatus, ExpressionArbiter
from dms.kernel.messages import Request, RobotCommand, RobotFeedback, UserPerception
from dms.kernel.ports import RobotPort
from dms.local_bus import InMemoryBus
from motivation import MotivationModel, Percepts
from sim.harness import Simulation
from sim.robot import SimRobot

START = datetime(2026, 11, 23, 10, 0, tzinfo=UTC)
HOUR = 3600.0
NOTHING = InputSnapshot(values={}, status={}, events=(), robot_params={}, env_params={})


# ---------------------------------------------------------------- the fake clock


def test_a_virtual_clock_can_have_its_wall_clock_set_without_moving_the_monotonic_one() -> None:
    clock = VirtualClock(START)
    clock.advance(10.0)
    clock.step_wall(-HOUR)
    assert clock.now() == START + timedelta(seconds=10.0 - HOUR)
    assert clock.monotonic() == 10.0
    clock.advance(0.5)
    assert clock.now() == START + timedelta(seconds=10.5 - HOUR)


def test_a_step_is_seen_once_and_drift_under_the_threshold_is_not_a_step() -> None:
    steps = WallSteps(threshold_s=2.0)
    clock = VirtualClock(START)
    seen = [steps.observe(clock.now(), clock.monotonic())]
    for _ in range(4):
        clock.advance(0.5)
        seen.append(steps.observe(clock.now(), clock.monotonic()))
    clock.step_wall(1.5)  # under the threshold: a slew, not a step
    clock.advance(0.5)
    seen.append(steps.observe(clock.now(), clock.monotonic()))
    clock.step_wall(-HOUR)
    clock.advance(0.5)
    seen.append(steps.observe(clock.now(), clock.monotonic()))
    for _ in range(4):
        clock.advance(0.5)
        seen.append(steps.observe(clock.now(), clock.monotonic()))
    assert [s for s in seen if s is not None] == [-HOUR]


def test_a_step_reads_as_its_direction_and_size() -> None:
    assert describe_step(-HOUR - 5) == "back 1 h 0 min 5 s"
    assert describe_step(125.0) == "forward 2 min 5 s"
    assert describe_step(2.5) == "forward 2.5 s"


# ---------------------------------------------------------------- the drives


def test_the_drives_go_on_at_their_rate_when_the_wall_clock_is_set_back_an_hour() -> None:
    model = MotivationModel()
    drives, clock = Drives(model), VirtualClock(START)
    stimuli = model.stimuli(Percepts())
    expected = None
    for tick in range(2 * 1200):  # 20 minutes at 2 Hz, the wall clock set back after 1
        if tick == 120:
            clock.step_wall(-HOUR)
            at_step = drives.state
        now = clock.now()
        drives.step(NOTHING, None, (), None, now, clock.monotonic())
        # what stepping the model by the ticks' real length gives, with the wall clock's
        # hour for the daily rhythm
        if expected is None:
            expected = model.initial_state(now)
        else:
            expected = model.step(expected, 0.5, stimuli, None, now)
        clock.advance(0.5)
    assert drives.state is not None and expected is not None and at_step is not None
    assert np.array_equal(drives.state.drives, expected.drives)
    assert not np.array_equal(drives.state.drives, at_step.drives), "not frozen for the hour"


def test_the_drives_do_not_age_by_an_hour_when_the_wall_clock_is_set_forward() -> None:
    model = MotivationModel()
    steady, stepped = Drives(model), Drives(model)
    clock = VirtualClock(START)
    for tick in range(4):
        now, monotonic = clock.now(), clock.monotonic()
        steady.step(NOTHING, None, (), None, now, monotonic)
        wall = now + timedelta(hours=1) if tick == 3 else now
        stepped.step(NOTHING, None, (), None, wall, monotonic)
        clock.advance(0.5)
    assert steady.state is not None and stepped.state is not None
    # the same half second of growth; only the hour of the rhythm differs, by a hair
    assert np.allclose(stepped.state.drives, steady.state.drives, atol=0.01)


# ---------------------------------------------------------------- robot commands


class _QuietRobot:
    """A robot that answers only what the test tells it to."""

    def __init__(self) -> None:
        self.sent: list[RobotCommand] = []
        self.feedback: list[RobotFeedback] = []

    def send(self, command: RobotCommand, now: datetime) -> None:
        self.sent.append(command)

    def interrupt(self, command_id: str, now: datetime) -> None:
        pass

    def poll(self, now: datetime) -> list[RobotFeedback]:
        out, self.feedback = self.feedback, []
        return out


def _arbiter() -> tuple[_QuietRobot, ExpressionArbiter, VirtualClock]:
    robot = _QuietRobot()
    port: RobotPort = robot
    arbiter = ExpressionArbiter(port, lambda _c: None, ack_timeout_s=10.0, done_timeout_s=120.0)
    return robot, arbiter, VirtualClock(START)


def _tick(arbiter: ExpressionArbiter, clock: VirtualClock) -> None:
    arbiter.set_monotonic(clock.monotonic())
    arbiter.update(clock.now())


def test_a_command_waiting_for_its_ack_does_not_time_out_when_the_wall_clock_jumps() -> None:
    robot, arbiter, clock = _arbiter()
    _tick(arbiter, clock)
    handle = arbiter.request("activity:x", "speech", "say", {"text": "hello"}, clock.now())
    clock.advance(0.5)
    clock.step_wall(HOUR)
    statuses = []
    for seconds in (0.0, 9.0, 0.5):  # ten seconds on the monotonic clock, at the end
        clock.advance(seconds)
        _tick(arbiter, clock)
        statuses.append(handle.status)
    assert statuses == [CommandStatus.SENT, CommandStatus.SENT, CommandStatus.TIMED_OUT]
    assert robot.sent[0].id == handle.command_id


def test_a_started_command_does_not_time_out_when_the_wall_clock_jumps() -> None:
    robot, arbiter, clock = _arbiter()
    _tick(arbiter, clock)
    handle = arbiter.request("activity:x", "motion", "gesture", {"name": "wave"}, clock.now())
    assert handle.command_id is not None
    robot.feedback.append(RobotFeedback(id=handle.command_id, status="started"))
    statuses = []
    for step in (0.0, HOUR, 0.0):
        clock.step_wall(step)
        clock.advance(0.5)
        _tick(arbiter, clock)
        statuses.append(handle.status)
        if step:  # the robot finishes it after the jump
            robot.feedback.append(RobotFeedback(id=handle.command_id, status="done"))
    assert statuses == [CommandStatus.STARTED, CommandStatus.STARTED, CommandStatus.DONE]
    assert arbiter.timeouts == 0


def test_a_wall_clock_set_back_does_not_stretch_a_timeout() -> None:
    _robot, arbiter, clock = _arbiter()
    _tick(arbiter, clock)
    handle = arbiter.request("activity:x", "speech", "say", {"text": "hello"}, clock.now())
    clock.step_wall(-HOUR)
    clock.advance(10.0)
    _tick(arbiter, clock)
    assert handle.status is CommandStatus.TIMED_OUT


ANN = UserPerception(present=True, user_id="ann", ready=True, engagement=None)


def test_an_activity_in_flight_goes_on_when_the_wall_clock_jumps_an_hour() -> None:
    settings = Settings.model_validate(
        {
            "controller": {"session_questions": 0, "question_every": 0},
            "inputs": {"stale_after_s": {"perception/user": 30.0}},
        }
    )
    with Simulation(settings, seed=1, start=START) as sim:
        sim.presence = ANN
        sim.feed(keys.PERCEPTION_USER, ANN)
        sim.run_for(119)
        # A speech the robot has started and not finished when the clock is set.
        sim.robot.set_fault("speech", "stall")
        sim.run_for(6)  # the menu went unanswered; bingo has begun, and speaks
        running = sim.controller.current
        assert running is not None and running.name == "bingo"
        in_flight = sim.stack.expression.pending()
        assert [h.status for h in in_flight] == [CommandStatus.STARTED]
        stepped_at = sim.t
        sim.clock.step_wall(HOUR)
        sim.run_for(15)
        assert sim.stack.expression.timeouts == 0
        assert in_flight[0].status is CommandStatus.STARTED
        assert sim.controller.current is running
        assert [d for d in sim.decisions if d.t >= stepped_at] == []


def test_an_offline_robot_is_still_probed_when_the_wall_clock_is_set_back() -> None:
    settings = Settings.model_validate(
        {
            "controller": {
                "ack_timeout_s": 2.0,
                "offline_after_unacked": 3,
                "offline_retry_max_s": 60.0,
                "session_questions": 0,
                "question_every": 0,
                "feedback_probability": 0.0,
            },
            "inputs": {"stale_after_s": {"perception/user": 30.0}},
        }
    )
    with Simulation(settings, seed=1, start=START) as sim:
        sim.presence = ANN
        sim.feed(keys.PERCEPTION_USER, ANN)
        sim.run_for(5)
        sim.robot.set_fault("*", "hang")
        sim.run_for(300)
        assert sim.last is not None and sim.last.state.robot_link == "offline"
        stepped_at = sim.t
        sim.clock.step_wall(-HOUR)
        sim.run_for(300)
        starts = [d.t for d in sim.decisions if d.t > stepped_at and d.decision.action == "start"]
        assert len(starts) >= 3, f"a probe at most every 60 s, not one an hour later: {starts}"


# ---------------------------------------------------------------- the daemon


def _robot(seed: int) -> RobotPort:
    return SimRobot(rng_seed=seed)


@pytest.fixture
def wired(tmp_path: Path) -> Iterator[tuple[Daemon, InMemoryBus, VirtualClock]]:
    """A started daemon over the in-memory bus, on a virtual clock."""
    settings = load_config(db=f"sqlite:///{tmp_path / 'dms.db'}", use_environment=False)
    bus, clock = InMemoryBus(), VirtualClock(START)
    daemon = Daemon(settings, print_decisions=False, bus=bus, clock=clock, sim_robot=_robot)
    daemon.start()
    try:
        yield daemon, bus, clock
    finally:
        daemon.close()


def _clock_reports(bus: InMemoryBus) -> list[str]:
    return [str(r["error"]) for r in bus.messages(keys.DMS_ERRORS) if r["key"] == "clock"]


def _ticks(daemon: Daemon, clock: VirtualClock, count: int) -> None:
    for _ in range(count):
        clock.advance(0.5)
        daemon._run_tick(urgent=False)


def test_the_daemon_reports_each_step_of_the_wall_clock_once(
    wired: tuple[Daemon, InMemoryBus, VirtualClock],
) -> None:
    daemon, bus, clock = wired
    _ticks(daemon, clock, 10)
    assert _clock_reports(bus) == []
    clock.step_wall(-HOUR)
    _ticks(daemon, clock, 20)
    reports = _clock_reports(bus)
    assert len(reports) == 1, reports
    assert "set back 1 h 0 min 0 s" in reports[0]
    clock.step_wall(2 * HOUR)
    _ticks(daemon, clock, 20)
    reports = _clock_reports(bus)
    assert len(reports) == 2 and "set forward 2 h 0 min 0 s" in reports[1], reports


# ---------------------------------------------------------------- the steady time


def test_the_steady_time_is_the_wall_time_until_the_wall_clock_is_set() -> None:
    clock, steady = VirtualClock(START), SteadyTime()
    seen = []
    for step in (0.0, 0.0, -HOUR, 0.0, 2 * HOUR, 0.0):
        clock.step_wall(step)
        clock.advance(0.5)
        steady.observe(clock.now(), clock.monotonic())
        seen.append(steady.steady(clock.now()))
    assert seen[:2] == [START + timedelta(seconds=0.5), START + timedelta(seconds=1.0)]
    assert seen == [START + timedelta(seconds=0.5 * (i + 1)) for i in range(6)]


# ---------------------------------------------------------------- dialogs and the menu


def _session(**controller: object) -> Simulation:
    settings = Settings.model_validate(
        {
            "controller": {"question_every": 0, "feedback_probability": 0.0, **controller},
            "inputs": {"stale_after_s": {"perception/user": 30.0}},
        }
    )
    sim = Simulation(settings, seed=2, start=START)
    sim.presence = ANN
    sim.feed(keys.PERCEPTION_USER, ANN)
    return sim


@pytest.mark.parametrize("step", [HOUR, -HOUR])
def test_a_question_open_when_the_wall_clock_is_set_keeps_its_whole_time(step: float) -> None:
    with _session(session_questions=1, question_timeout_s=15.0) as sim:
        sim.run_for(1)
        question = sim.controller.dialog
        assert question is not None and question.kind is DialogKind.GENERAL_QUESTION
        asked_at = sim.t
        sim.clock.step_wall(step)
        sim.run_for(13)
        assert sim.controller.dialog is question, "not ended unanswered by the step"
        assert sim.controller.counters.unanswered == 0
        sim.run_for(asked_at + 16 - sim.t)  # its 15 s, on the monotonic clock
        assert sim.controller.dialog is not question, "not stretched by the step either"
        assert sim.controller.counters.unanswered == 1


@pytest.mark.parametrize("step", [HOUR, -HOUR])
def test_a_menu_open_when_the_wall_clock_is_set_waits_its_whole_time(step: float) -> None:
    with _session(session_questions=0, menu_timeout_s=20.0) as sim:
        sim.run_for(1)
        sim.feed(keys.REQUEST, Request(action="start", activity="menu", by="ann"))
        sim.run_for(0.5)
        menu = sim.controller.current
        assert menu is not None and menu.name == "menu"
        offered_at = sim.t
        sim.clock.step_wall(step)
        sim.run_for(18)
        assert sim.controller.current is menu, "the menu is not ended by the step"
        sim.run_for(offered_at + 21 - sim.t)
        ended = [d for d in sim.decisions if d.decision.activity == "menu" and d.t > offered_at]
        assert [d.decision.action for d in ended][:1] == ["cancel"], ended
        assert 20 <= ended[0].t - offered_at <= 21, "its 20 s, on the monotonic clock"


# ---------------------------------------------------------------- an activity's own times


def _steady_activity(tmp_path: Path, yaml: str) -> tuple[Activity, VirtualClock, SteadyTime]:
    (tmp_path / "timed.yaml").write_text(textwrap.dedent(yaml).lstrip())
    library = BehaviorLibrary.load(tmp_path)
    clock, steady = VirtualClock(START), SteadyTime()
    arbiter = ExpressionArbiter(SimRobot(), lambda _c: None)
    ctx = ActivityContext(expression=arbiter, source="activity:timed", steady=steady.steady)
    activity = library.create("timed", ctx, {})
    steady.observe(clock.now(), clock.monotonic())
    activity.start(clock.now())
    return activity, clock, steady


def _run(activity: Activity, clock: VirtualClock, steady: SteadyTime, seconds: float) -> None:
    for _ in range(round(seconds / 0.5)):
        clock.advance(0.5)
        steady.observe(clock.now(), clock.monotonic())
        activity.tick(clock.now())


WAITS = """
name: timed
outcomes: [done, preempted]
states:
  WAIT:
    wait: {seconds: 30}
    transitions: {done: done, preempted: TIDY}
  TIDY:
    wait: {seconds: 100}
    transitions: {done: preempted}
"""


@pytest.mark.parametrize("step", [HOUR, -HOUR])
def test_an_activity_waits_its_seconds_across_a_step_of_the_wall_clock(
    tmp_path: Path, step: float
) -> None:
    activity, clock, steady = _steady_activity(tmp_path, WAITS)
    _run(activity, clock, steady, 10)
    clock.step_wall(step)
    _run(activity, clock, steady, 19.5)
    assert not activity.finished, "not cut short by a step forward"
    _run(activity, clock, steady, 0.5)
    assert activity.status is ActivityStatus.COMPLETED, "nor stretched by a step back"


@pytest.mark.parametrize("step", [HOUR, -HOUR])
def test_a_cleanup_is_cut_off_at_its_limit_across_a_step_of_the_wall_clock(
    tmp_path: Path, step: float
) -> None:
    activity, clock, steady = _steady_activity(tmp_path, WAITS)
    _run(activity, clock, steady, 1)
    activity.preempt(clock.now(), limit_s=5)
    assert activity.state_path == "TIDY"
    clock.step_wall(step)
    _run(activity, clock, steady, 4.5)
    assert activity.stopping
    _run(activity, clock, steady, 0.5)
    assert activity.status is ActivityStatus.CANCELLED


# ---------------------------------------------------------------- new users


@pytest.mark.parametrize("step", [HOUR, -HOUR])
def test_a_new_user_is_stored_after_new_user_after_s_across_a_step(
    tmp_path: Path, step: float
) -> None:
    settings = Settings.model_validate(
        {
            "db": f"sqlite:///{tmp_path / 'dms.db'}",
            "controller": {"session_questions": 0, "question_every": 0, "new_user_after_s": 3.0},
        }
    )
    with Simulation(settings, seed=3, start=START) as sim:
        sim.presence = ANN
        sim.feed(keys.PERCEPTION_USER, ANN)
        sim.run_for(1)
        sim.clock.step_wall(step)
        sim.run_for(1.5)
        assert sim.stack.store is not None and sim.stack.store.list_ids() == []
        sim.run_for(1)
        assert sim.stack.store.list_ids() == ["ann"]


def test_the_daemon_on_the_simulated_robot_goes_on_when_the_wall_clock_is_set_back(
    wired: tuple[Daemon, InMemoryBus, VirtualClock],
) -> None:
    daemon, bus, clock = wired
    _ticks(daemon, clock, 2)
    bus.inject(keys.REQUEST, {"action": "start", "activity": "bingo", "by": "app"})
    _ticks(daemon, clock, 2)  # sent, then started
    in_flight = daemon.stack.expression.pending()
    assert in_flight and all(h.status is CommandStatus.STARTED for h in in_flight)
    clock.step_wall(-HOUR)
    _ticks(daemon, clock, 2 * 150)  # past the 120 s a stalled command would wait
    decisions = bus.messages(keys.DMS_DECISION)
    assert [d["action"] for d in decisions if d["activity"] == "bingo"][:1] == ["start"]
    assert [d for d in decisions if d["action"] == "fail"] == []
    assert daemon.stack.expression.timeouts == 0
    assert all(h.status is CommandStatus.DONE for h in in_flight)


@pytest.mark.parametrize("step", [HOUR, -HOUR])
def test_a_run_cut_here_is_resumed_within_its_window_across_a_step(
    tmp_path: Path, step: float
) -> None:
    settings = Settings.model_validate(
        {
            "db": f"sqlite:///{tmp_path / 'dms.db'}",
            "controller": {
                "session_questions": 0,
                "question_every": 0,
                "feedback_probability": 0.0,
                "resume_cut_within_s": 120.0,
            },
        }
    )
    with Simulation(settings, seed=3, start=START) as sim:
        sim.presence = ANN
        sim.feed(keys.PERCEPTION_USER, ANN)
        sim.run_for(5)
        sim.feed(keys.REQUEST, Request(action="start", activity="quiz", by="ann"))
        sim.run_for(20)
        sim.unseat()
        sim.run_for(30)
        assert [d.decision.reason for d in sim.decisions].count("user_left") == 1
        sim.clock.step_wall(step)
        sim.run_for(30)
        back_at = sim.t
        sim.presence = ANN
        sim.feed(keys.PERCEPTION_USER, ANN)
        sim.run_for(2)
        resumed = [d for d in sim.decisions if d.t >= back_at and d.decision.reason == "resumed"]
        assert [d.decision.activity for d in resumed] == ["quiz"]
        assert (resumed[0].decision.detail or "").startswith("cut 6"), resumed[0].decision.detail


def test_an_activity_that_spans_a_step_back_is_stored_when_it_ends() -> None:
    """Its two ends are named by the wall clock, set back an hour in between: the run is
    still stored (the store refuses an end before the start), not lost."""
    settings = Settings.model_validate({"controller": {"session_questions": 0}})
    with Simulation(settings, seed=1, start=START) as sim:
        sim.presence = ANN
        sim.feed(keys.PERCEPTION_USER, ANN)
        sim.run_for(30)
        sim.feed(keys.REQUEST, Request(action="start", activity="jokes", by="caregiver"))
        sim.run_for(5)
        assert sim.controller.current is not None and sim.controller.current.name == "jokes"
        sim.clock.step_wall(-HOUR)
        sim.run_for(5)
        sim.feed(keys.REQUEST, Request(action="cancel", activity="jokes", by="caregiver"))
        sim.run_for(5)
        jokes = [d.decision.action for d in sim.decisions if d.decision.activity == "jokes"]
        assert jokes[-1] == "cancel", jokes
        assert [e for e in sim.errors if "before started" in e[2]] == []
        assert sim.stack.store is not None
        last = sim.stack.store.last_run("ann")
        assert last is not None and (last["activity"], last["outcome"]) == ("jokes", "stopped")
