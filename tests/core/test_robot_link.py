"""A silent robot: marked offline, nothing started but rare probes, back at once when it speaks."""

from __future__ import annotations

import itertools
from datetime import UTC, datetime

from dms.config import Settings
from dms.kernel import keys
from dms.kernel.messages import Request, UserPerception
from sim.harness import Simulation

START = datetime(2026, 11, 23, 10, 0, tzinfo=UTC)


ANN = UserPerception(present=True, user_id="ann", ready=True, engagement=None)


def _sim() -> Simulation:
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
    sim = Simulation(settings, seed=1, start=START)
    sim.presence = ANN  # someone to talk to: the robot sends commands
    sim.feed(keys.PERCEPTION_USER, ANN)
    return sim


def _starts(sim: Simulation, since: float) -> list[float]:
    return [d.t for d in sim.decisions if d.t >= since and d.decision.action == "start"]


def test_a_silent_robot_goes_offline_and_is_probed_with_backoff() -> None:
    with _sim() as sim:
        sim.run_for(5)
        assert sim.last is not None and sim.last.state.robot_link == "ok"
        sim.robot.set_fault("*", "hang")  # the robot hears nothing and says nothing
        silent_at = sim.t
        sim.run_for(600)
        assert sim.last is not None and sim.last.state.robot_link == "offline"
        offline = [e for e in sim.errors if e[1] == "robot" and "offline" in e[2]]
        assert len(offline) == 1, "said once when it happens, not at every tick"
        starts = _starts(sim, silent_at + 30)
        # without the backoff, a start every ack timeout or so: ~100 in these 570 s
        assert 1 <= len(starts) <= 15, starts
        gaps = [round(b - a) for a, b in itertools.pairwise(starts)]
        assert gaps == sorted(gaps), f"the waits between probes grow: {gaps}"
        assert gaps[-1] == 60, f"and stop growing at offline_retry_max_s: {gaps}"


def test_a_request_while_offline_is_answered_not_dropped() -> None:
    with _sim() as sim:
        sim.robot.set_fault("*", "hang")
        sim.run_for(30)
        assert sim.last is not None and sim.last.state.robot_link == "offline"
        mark = len(sim.decisions)
        sim.feed(keys.REQUEST, Request(action="start", activity="quiz", by="app"))
        sim.tick(urgent=True)
        answered = [d.decision for d in sim.decisions[mark:]]
        assert any(
            d.action == "fail" and d.activity == "quiz" and d.detail == "the robot is offline"
            for d in answered
        ), answered


def test_the_robot_is_back_at_once_when_it_speaks_again() -> None:
    with _sim() as sim:
        sim.robot.set_fault("*", "hang")
        sim.run_for(200)
        assert sim.last is not None and sim.last.state.robot_link == "offline"
        sim.robot.set_fault("*", None)
        sim.controller.deps.expression.robot_seen()  # what the daemon does on its token
        back_at = sim.t
        sim.run_for(10)
        assert sim.last.state.robot_link == "ok"
        assert _starts(sim, back_at), "an activity starts again within seconds"
        assert any(e[1] == "robot" and "back online" in e[2] for e in sim.errors)
