"""The fault barrier: an exception injected into each step of a tick, in turn.

Each case runs the real controller stack (real SQLite, the simulated Mini) on a virtual
clock with a user in front of the robot, makes one collaborator of one step raise for
20 virtual seconds, then lets it work again. The loop must go on ticking, report the
fault on ``dms/errors`` as ``tick/<step>`` naming what it was working on (once, not at
every tick), keep its outputs consistent, and decide normally once the fault is gone.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from datetime import UTC, datetime
from typing import Any

import pytest

from dms.config import Settings
from dms.controller import TickRecord
from dms.faults import FaultBarrier
from dms.kernel import keys
from dms.kernel.messages import Request, Touch, UserPerception
from sim.harness import Simulation

START = datetime(2026, 11, 23, 10, 0, tzinfo=UTC)
ANN = UserPerception(present=True, user_id="ann", ready=True, engagement=0.8)


class Boom(RuntimeError):
    """The injected fault."""


@contextmanager
def raising(target: Any, name: str) -> Iterator[list[int]]:
    """Make ``target.name`` raise Boom while the block runs; yields the call count."""
    calls = [0]
    original = getattr(target, name)

    def broken(*_args: Any, **_kwargs: Any) -> Any:
        calls[0] += 1
        raise Boom(f"injected into {name}")

    setattr(target, name, broken)
    try:
        yield calls
    finally:
        setattr(target, name, original)


def _settings() -> Settings:
    return Settings.model_validate(
        {
            "seed": 5,
            "inputs": {"stale_after_s": {"perception/user": 30.0}},
            "controller": {
                "session_questions": 0,
                "question_every": 0,
                "feedback_probability": 0.0,
            },
        }
    )


def _targets(sim: Simulation) -> dict[str, tuple[Any, str]]:
    controller = sim.controller
    deps = controller.deps
    return {
        "motivation": (deps.motivation, "step"),
        "robot": (deps.expression, "update"),
        "memory": (deps.profiles, "retry"),
        "user": (controller.choice, "follow_user"),
        "dialog": (controller.dialogs, "advance"),
        "cleanup": (controller.runner, "wind_down"),
        "activity": (controller.choice, "follow_activity"),
        "cancel": (controller.choice, "due_items"),
        "choose": (controller.choice, "choose"),
        "event/request": (controller.events, "on_request"),
    }


STEPS = [
    "motivation",
    "robot",
    "memory",
    "user",
    "dialog",
    "cleanup",
    "activity",
    "cancel",
    "choose",
    "event/request",
]


def _last(sim: Simulation) -> TickRecord:
    assert sim.last is not None
    return sim.last


def _ready_sim() -> Simulation:
    sim = Simulation(_settings(), seed=5, start=START)
    sim.presence = ANN
    sim.feed(keys.PERCEPTION_USER, ANN)
    sim.run_for(30)
    return sim


def _broken_for(sim: Simulation, step: str, seconds: float, during: Callable[[], None]) -> int:
    target, name = _targets(sim)[step]
    with raising(target, name) as calls:
        during()
        sim.run_for(seconds)
    return calls[0]


@pytest.mark.parametrize("step", STEPS)
def test_a_fault_in_any_step_is_reported_and_the_loop_goes_on(step: str) -> None:
    with _ready_sim() as sim:
        ticks_before = sim.ticks
        broken_at = sim.t

        def during() -> None:
            if step == "event/request":
                sim.feed(keys.REQUEST, Request(action="start", activity="jokes", by="app"))
                sim.tick(urgent=True)
            if step == "choose":  # nothing runs: the robot must choose during the fault
                sim.feed(keys.REQUEST, Request(action="cancel", by="app"))
                sim.tick(urgent=True)
            if step == "cleanup":  # a quiz cancelled mid-question cleans up during the fault
                sim.feed(keys.REQUEST, Request(action="start", activity="quiz", by="app"))
                sim.tick(urgent=True)
                for _ in range(240):  # virtual half-seconds, until the first question
                    state = sim.controller.build_state(sim.now()).activity
                    if state is not None and "ASK" in state.state:
                        break
                    sim.run_for(0.5)
                sim.feed(keys.REQUEST, Request(action="start", activity="jokes", by="app"))
                sim.tick(urgent=True)
            if step == "dialog":  # the shoulder's "continue or stop?" is open during the fault
                sim.feed(keys.PERCEPTION_TOUCH, Touch(part="right_shoulder", kind="tap"))
                sim.tick(urgent=True)

        calls = _broken_for(sim, step, 20, during)
        assert calls >= 1, f"the injected fault in {step} was never reached"
        assert sim.ticks - ticks_before >= 40, "the loop stopped ticking"
        reports = [e for e in sim.errors if e[0] >= broken_at and e[1] == f"tick/{step}"]
        assert reports, f"no tick/{step} report; got {sim.errors[-5:]}"
        assert len(reports) == 1, f"a fault repeated every tick is reported once: {reports}"
        assert "Boom: injected" in reports[0][2] and "the loop goes on" in reports[0][2]
        if step == "event/request":
            assert "jokes" in reports[0][2], "the report names the input that caused it"

        _assert_consistent(sim)

        sim.run_for(5)
        current = sim.controller.current
        wanted = "weather" if current is None or current.name != "weather" else "sayings"
        sim.feed(keys.REQUEST, Request(action="start", activity=wanted, by="app"))
        record = sim.tick(urgent=True)
        started = [d.activity for d in record.decisions if d.action == "start"]
        assert started == [wanted], f"after the fault in {step}, a request is not served"
        user = _last(sim).state.user
        assert user is not None and user.id == "ann"
        activity = _last(sim).state.activity
        assert activity is None or activity.status == "running" or sim.controller.dialog, (
            f"left paused with nothing to resume it after the fault in {step}"
        )


def test_a_failing_activity_step_fails_the_activity_cleanly() -> None:
    with _ready_sim() as sim:
        assert sim.controller.current is not None
        running = sim.controller.current.name
        with raising(sim.controller.choice, "check_cancel_reasons"):
            sim.tick()
        decisions = [d.decision for d in sim.decisions if d.decision.tick == _last(sim).tick]
        assert decisions[0].action == "fail" and decisions[0].activity == running, decisions
        assert decisions[0].reason == "activity_error"
        assert "cancel step failed" in (decisions[0].detail or "")
        _assert_consistent(sim)


def _assert_consistent(sim: Simulation) -> None:
    """Each manager runs an activity exactly when the controller believes it does."""
    controller = sim.controller
    believed = {r.manager: r.name for r in (controller.current, controller.suspended) if r}
    for name, manager in controller.managers.items():
        assert manager.activity_name == believed.get(name), (name, manager.activity_name)
    state = _last(sim).state
    assert (state.activity and state.activity.name) == (
        controller.current and controller.current.name
    )


def test_a_fault_that_keeps_coming_back_is_reported_again_after_a_minute() -> None:
    with _ready_sim() as sim:
        with raising(sim.controller.deps.motivation, "step"):
            sim.run_for(150)
        reports = [e for e in sim.errors if e[1] == "tick/motivation"]
        assert 2 <= len(reports) <= 4, reports
        assert "again" in reports[1][2]


def test_the_barrier_returns_whether_a_step_ran_and_lets_an_interrupt_through() -> None:
    reports: list[tuple[str, str]] = []
    barrier = FaultBarrier(lambda key, line: reports.append((key, line)))
    done: list[int] = []

    assert barrier.run("ok", None, done.append, 1) is True
    assert done == [1] and reports == []

    def broken(x: int, *, by: str) -> None:
        raise Boom(f"{x} by {by}")

    assert barrier.run("broken", "ann", broken, 2, by="test") is False
    assert reports == [("tick/broken", "Boom: 2 by test on 'ann'; the loop goes on")]
    assert [(f.step, f.subject) for f in barrier.faults] == [("broken", "'ann'")]

    def interrupted() -> None:
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        barrier.run("interrupted", None, interrupted)
    assert len(reports) == 1
