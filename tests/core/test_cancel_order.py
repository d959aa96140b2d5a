"""The paper's four reasons to cancel an activity are checked and recorded in its order,
(a) motivation, (b) the user's request, (c) a high-priority agenda item, (d) the activity
failed or asked for another, whatever else falls on the same tick.

Real controller stack on a virtual clock with a scripted user: the robot's speech fails,
so the robot's first activity fails on a tick the first run finds; the second run, the
same but for one more reason due on that very tick, must record that reason instead.
"""

from __future__ import annotations

from collections.abc import Callable

from agenda import ItemSpec
from dms.kernel import keys
from dms.kernel.messages import Decision, Request
from sim.harness import Simulation
from tests.core.scripted import quiet_settings, seated

ROBOT_CHOOSES = {"user_initiative": {"unknown": 0.0}}


def _run(before: Callable[[Simulation], None] | None = None) -> tuple[str, float, list[Decision]]:
    """The robot's first activity with speech failing from 1 s: its name, the virtual
    second its first decision after the start falls on, and that tick's decisions."""
    with seated(quiet_settings(ROBOT_CHOOSES)) as sim:
        sim.run_for(1)
        first = sim.decisions[0].decision
        assert first.action == "start" and first.activity is not None
        sim.robot.set_fault("speech", "fail")
        if before is not None:
            before(sim)
        sim.run_for(20)
        later = sim.decisions[1:]
        assert later, "the failing speech ends the activity"
        at = later[0].t
        return first.activity, at, [timed.decision for timed in later if timed.t == at]


def _failure_tick() -> tuple[str, float]:
    activity, at, decisions = _run()
    first = decisions[0]
    assert (first.action, first.activity, first.reason) == ("fail", activity, "activity_error")
    return activity, at


def test_a_high_priority_event_due_on_the_tick_the_activity_fails_is_the_reason() -> None:
    activity, failed_at = _failure_tick()

    def event(sim: Simulation) -> None:
        agenda = sim.stack.agenda
        assert agenda is not None
        data = {
            "user_id": "ann",
            "kind": "event",
            "activity": "cognitive_stimulation",
            "priority": "high",
            "at": sim.when(failed_at),
        }
        agenda.add(ItemSpec.from_data(data), sim.now())

    _, at, decisions = _run(event)
    assert at == failed_at
    assert [(d.action, d.activity, d.reason) for d in decisions] == [
        ("cancel", activity, "agenda"),
        ("start", "cognitive_stimulation", "agenda"),
    ]


def test_a_request_on_the_tick_the_activity_fails_is_the_reason() -> None:
    activity, failed_at = _failure_tick()
    wanted = "bingo" if activity != "bingo" else "quiz"

    def request(sim: Simulation) -> None:
        asked = Request(action="start", activity=wanted, by="ann")
        sim.at(failed_at, lambda: sim.feed(keys.REQUEST, asked))

    _, at, decisions = _run(request)
    assert at == failed_at
    assert [(d.action, d.activity, d.reason) for d in decisions][:2] == [
        ("cancel", activity, "user_request"),
        ("start", wanted, "user_request"),
    ]
    assert not [d for d in decisions if d.action == "fail" and d.activity == activity]


def test_a_request_and_a_high_priority_event_on_one_tick_the_request_first() -> None:
    _, failed_at = _failure_tick()
    due = failed_at - 2.0  # before the failure: only the two reasons meet

    def both(sim: Simulation) -> None:
        agenda = sim.stack.agenda
        assert agenda is not None
        data = {
            "user_id": "ann",
            "kind": "event",
            "activity": "cognitive_stimulation",
            "priority": "high",
            "at": sim.when(due),
        }
        agenda.add(ItemSpec.from_data(data), sim.now())
        asked = Request(action="start", activity="bingo", by="ann")
        sim.at(due, lambda: sim.feed(keys.REQUEST, asked))

    _, at, decisions = _run(both)
    assert at == due
    assert (decisions[0].action, decisions[0].reason) == ("cancel", "user_request")
