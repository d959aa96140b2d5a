"""The paper's four reasons to cancel an activity are checked and recorded in its order,
(a) motivation, (b) the user's request, (c) a high-priority agenda item, (d) the activity
failed or asked for another, whatever else falls on the same tick.

Real controller stack on a virtual clock with a scripted user: the robot's speech fails,
so the jokes a caregiver asks for fail on a tick the first run finds; the second run,
the same but for one more reason due on that very tick, must record that reason instead.
"""

from __future__ import annotations

from collections.abc import Callable

from agenda import ItemSpec
from dms.kernel import keys
from dms.kernel.messages import Decision, Request
from sim.harness import Simulation
from tests.core.scripted import quiet_settings, seated

ROBOT_CHOOSES = {"user_initiative": {"unknown": 0.0}}


def _run(before: Callable[[Simulation], None] | None = None) -> tuple[float, list[Decision]]:
    """The jokes, asked for by a caregiver once the robot's speech fails: the virtual
    second of the first decision after their start, and that tick's decisions."""
    with seated(quiet_settings(ROBOT_CHOOSES)) as sim:
        sim.run_for(1)
        sim.robot.set_fault("speech", "fail")
        sim.feed(keys.REQUEST, Request(action="start", activity="jokes", by="caregiver"))
        sim.tick(urgent=True)
        last = sim.decisions[-1].decision
        assert (last.action, last.activity) == ("start", "jokes")
        mark = len(sim.decisions)
        if before is not None:
            before(sim)
        sim.run_for(20)
        later = sim.decisions[mark:]
        assert later, "the failing speech ends the jokes"
        at = later[0].t
        return at, [timed.decision for timed in later if timed.t == at]


def _failure_tick() -> float:
    at, decisions = _run()
    first = decisions[0]
    assert (first.action, first.activity, first.reason) == ("fail", "jokes", "activity_error")
    return at


def _high_priority_event(sim: Simulation, due: float) -> None:
    """Ann's high-priority cognitive stimulation, due at virtual second ``due``."""
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


def test_a_high_priority_event_due_on_the_tick_the_activity_fails_is_the_reason() -> None:
    failed_at = _failure_tick()

    def event(sim: Simulation) -> None:
        _high_priority_event(sim, failed_at)

    at, decisions = _run(event)
    assert at == failed_at
    assert [(d.action, d.activity, d.reason) for d in decisions] == [
        ("cancel", "jokes", "agenda"),
        ("start", "cognitive_stimulation", "agenda"),
    ]


def test_a_request_on_the_tick_the_activity_fails_is_the_reason() -> None:
    failed_at = _failure_tick()
    wanted = "bingo"

    def request(sim: Simulation) -> None:
        asked = Request(action="start", activity=wanted, by="ann")
        sim.at(failed_at, lambda: sim.feed(keys.REQUEST, asked))

    at, decisions = _run(request)
    assert at == failed_at
    assert [(d.action, d.activity, d.reason) for d in decisions][:2] == [
        ("cancel", "jokes", "user_request"),
        ("start", wanted, "user_request"),
    ]
    assert not [d for d in decisions if d.action == "fail" and d.activity == "jokes"]


def test_a_request_an_event_and_an_error_on_one_tick_the_request_first() -> None:
    due = _failure_tick()  # three reasons on one tick: (b), (c) and (d)

    def both(sim: Simulation) -> None:
        _high_priority_event(sim, due)
        asked = Request(action="start", activity="bingo", by="ann")
        sim.at(due, lambda: sim.feed(keys.REQUEST, asked))

    at, decisions = _run(both)
    assert at == due
    assert (decisions[0].action, decisions[0].reason) == ("cancel", "user_request")
