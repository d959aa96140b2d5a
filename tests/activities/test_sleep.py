"""A waiting machine sleeps: the ticks it skips change nothing.

After a tick that left it running, the activity asks its active states what they
wait for (:class:`activities.engine.Wake`) and skips its ticks until that moves or
something reaches it from outside. Each test runs the same activity twice, once with
sleeping and once without (its root never says it can sleep), and compares what they
did after every step: the same states at the same ticks, the same commands.
"""

from __future__ import annotations

import random
from datetime import timedelta
from pathlib import Path
from typing import Any

import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from activities import Activity, ActivityStatus, BehaviorLibrary
from activities.engine import Node
from dms.kernel.expression import Priority
from dms.kernel.messages import ScreenChoice, Speech, Touch
from tests.activities.conftest import Bench, write_behaviors

LIBRARY = BehaviorLibrary.load()
OPS = st.sampled_from(
    ["tick", "tick", "wait", "long", "pause", "resume", "answer", "screen", "touch", "stop"]
)

WAITING = """
name: waiting
outcomes: [done, stopped]
states:
  GUARDED:
    guard:
      state:
        WORK:
          state_machine:
            outcomes: [done]
            states:
              SAY:
                speak: {text: "one two three four five six seven eight nine ten"}
                transitions: {done: PAUSE}
              PAUSE:
                wait: {seconds: 7.3}
                transitions: {done: BOTH}
              BOTH:
                concurrence:
                  outcomes: [done]
                  default_outcome: done
                  wait: all
                  states:
                    SHOW: {show: {text: "hello"}}
                    NAP: {wait: {seconds: 4}}
      timer_s: 30
      keywords: [stop]
      outcome: stopped
    transitions: {done: done, stopped: stopped}
"""


def _awake(activity: Activity) -> Activity:
    """The same activity that never sleeps: its root never says what it waits for."""
    activity.root.wake = lambda now: None  # type: ignore[method-assign]
    return activity


def _twins(make: Any, name: str, behavior: str) -> list[tuple[Bench, Activity]]:
    """The same activity twice, each on a bench of its own: one that sleeps, one that
    never does."""
    twins = []
    for never_sleeps in (False, True):
        bench: Bench = make({name: behavior})
        activity = bench.create(name)
        twins.append((bench, _awake(activity) if never_sleeps else activity))
    return twins


def _trace(bench: Bench, activity: Activity) -> tuple[Any, ...]:
    return (
        bench.now,
        activity.status,
        activity.state_path,
        [(c.channel, c.action, c.args) for c in bench.commands],
        [(h.channel, h.status) for h in bench.expression.pending()],
    )


def _apply(bench: Bench, activity: Activity, op: str) -> None:
    if op == "tick":
        bench.advance(activity, 0.5)
    elif op == "wait":
        bench.advance(activity, 3.0)
    elif op == "long":
        bench.advance(activity, 20.0)
    elif op == "pause":
        activity.pause(bench.now)
    elif op == "resume":
        activity.resume(bench.now)
    elif op == "answer":
        activity.deliver(Speech(text="Paris stop", confidence=0.9))
    elif op == "screen":
        activity.deliver(ScreenChoice(choice="quiz"))
    elif op == "touch":
        activity.deliver(Touch(part="left_shoulder", kind="tap"))
    else:
        activity.preempt(bench.now, limit_s=10.0)


@settings(max_examples=60, deadline=None)
@given(
    name=st.sampled_from(["quiz", "bingo", "dance", "talk", "multimedia", "menu", "notification"]),
    ops=st.lists(OPS, max_size=40),
)
def test_a_sleeping_activity_does_what_an_awake_one_does(name: str, ops: list[str]) -> None:
    sleeping, awake = Bench(LIBRARY, seed=3), Bench(LIBRARY, seed=3)
    asleep = sleeping.start(sleeping.create(name))
    ticking = awake.start(_awake(awake.create(name)))
    for op in [*ops, "long", "long"]:
        _apply(sleeping, asleep, op)
        _apply(awake, ticking, op)
        assert _trace(sleeping, asleep) == _trace(awake, ticking), op
    assert asleep.result == ticking.result
    assert ticking.skipped == 0


def test_a_machine_that_waits_skips_its_ticks_and_wakes_on_time(make: Any) -> None:
    runs = []
    for bench, activity in _twins(make, "waiting", WAITING):
        updates: list[str] = []
        for state in _states(activity.root):
            update = state.update

            def counted(
                now: Any, state: Node = state, update: Any = update, seen: list[str] = updates
            ) -> Any:
                seen.append(state.name)
                return update(now)

            state.update = counted  # type: ignore[method-assign]
        bench.start(activity)
        entered: list[tuple[str, float]] = []
        while not activity.finished:
            bench.advance(activity, 0.5)
            path = activity.state_path
            if not entered or entered[-1][0] != path:
                entered.append((path, (bench.now - activity.started_at).total_seconds()))  # type: ignore[operator]
            assert bench.now - activity.started_at < timedelta(minutes=2)  # type: ignore[operator]
        runs.append((entered, activity.result.outcome, len(updates), activity.skipped))
    (slept, outcome, updates_slept, skipped), (ticked, outcome_awake, updates_awake, _) = runs
    assert slept == ticked, "the same states, entered at the same ticks"
    assert outcome == outcome_awake == "done"
    assert skipped > 10, "it slept through the speech and the waits"
    assert updates_slept < updates_awake / 2


FOREVER = """
name: forever
outcomes: [done, stopped, late]
states:
  G:
    guard:
      state: {NAP: {wait: {seconds: null}}}
      keywords: [stop]
      timer_s: 12.2
      outcome: fired
    transitions: {fired: stopped}
"""


def test_an_event_wakes_a_sleeping_machine(make: Any) -> None:
    bench: Bench = make({"forever": FOREVER})
    activity = bench.start(bench.create("forever"))
    bench.advance(activity, 2.0)
    skipped = activity.skipped
    bench.advance(activity, 2.0)
    assert activity.skipped > skipped, "asleep: the wait has no end, the timer is far"
    assert activity.deliver(Speech(text="please stop", confidence=0.9))
    bench.advance(activity, 0.5)
    assert activity.status is ActivityStatus.COMPLETED, "the guard fired at the next tick"
    assert activity.result.outcome == "stopped"


def test_a_preemption_wakes_a_sleeping_machine(make: Any) -> None:
    bench: Bench = make({"forever": FOREVER})
    activity = bench.start(bench.create("forever"))
    bench.advance(activity, 4.0)
    assert activity.skipped > 0
    activity.preempt(bench.now, limit_s=5.0)
    assert activity.status is ActivityStatus.CANCELLED, "the request is served at once"
    assert activity.result.outcome == "preempted"


def test_a_guard_timer_wakes_a_sleeping_machine(make: Any) -> None:
    bench: Bench = make({"forever": FOREVER})
    activity = bench.start(bench.create("forever"))
    bench.run_until(activity, lambda: activity.finished)
    assert activity.result.outcome == "stopped"
    assert activity.started_at is not None
    assert bench.now - activity.started_at == timedelta(seconds=12.5), "the first tick after"
    assert activity.skipped >= 20


LOOPING = """
name: looping
outcomes: [done]
userdata: {n: 0}
states:
  COUNT:
    set_data: {add: {n: 1}}
    transitions: {done: ENOUGH}
  ENOUGH:
    check: {value: "{n}", at_least: 450}
    transitions: {met: NAP, not_met: COUNT}
  NAP:
    wait: {seconds: 2}
    transitions: {done: ROUNDS}
  ROUNDS:
    iterator:
      items: 300
      continue_on: [done]
      state: {IT: {set_data: {add: {n: 1}}}}
    transitions: {done: LAST}
  LAST:
    wait: {seconds: 1}
    transitions: {done: done}
"""


def test_a_tick_cut_short_by_the_step_limit_does_not_sleep(make: Any) -> None:
    """A machine that runs out of steps in a tick ends it with a state still to enter:
    it must not sleep then (its next tick enters that state), though its last state
    was left waiting."""
    runs = []
    for bench, activity in _twins(make, "looping", LOOPING):
        bench.start(activity)
        trace = []
        while not activity.finished:
            bench.advance(activity, 0.5)
            trace.append((activity.state_path, activity.userdata.get("n")))
            assert len(trace) < 100
        runs.append((trace, activity.result.outcome, activity.skipped))
    (slept, outcome, skipped), (ticked, outcome_awake, _) = runs
    assert slept == ticked, "the same states and counts at every tick"
    assert [n for _, n in ticked[:2]] == [200, 300], "200 steps a tick (the first at start)"
    assert outcome == outcome_awake == "done"
    assert skipped > 0, "it slept in its waits"


# ------------------------------------------------------------ random machines

CHANNELS = ["speech", "screen", "motion", "media", "led"]
LEAVES: list[tuple[dict[str, Any], tuple[str, ...]]] = [
    ({"speak": {"text": "one two three four five", "priority": "high"}}, ("done",)),
    ({"speak": {"text": "one"}}, ("done",)),
    ({"show": {"text": "hi"}}, ("done",)),
    ({"leds": {"color": "red"}}, ("done",)),
    ({"play_media": {"title": "a song", "duration_s": 1.3}}, ("done",)),
    ({"gesture": {"name": "wave"}}, ("done",)),
    ({"gesture": {"name": "wave", "toward": "user"}}, ("done",)),
    ({"wait": {"seconds": 0.7}}, ("done",)),
    ({"wait": {"seconds": 2.25}}, ("done",)),
    ({"wait": {"seconds": None}}, ("done",)),
    (
        {"ask": {"question": "where?", "choices": ["paris", "rome"], "timeout_s": 2.0}},
        ("answered", "no_answer"),
    ),
    ({"wait_event": {"touch": ["left_shoulder"], "timeout_s": 3.0}}, ("event", "timeout")),
    ({"set_data": {"add": {"n": 1}}}, ("done",)),
]


def _state(rng: random.Random, depth: int) -> tuple[dict[str, Any], tuple[str, ...]]:
    """A random state and its outcomes: leaves, machines, concurrences, iterators, guards."""
    if depth >= 3 or rng.random() < 0.45:
        leaf, outcomes = rng.choice(LEAVES)
        return dict(leaf), outcomes
    kind = rng.choice(["machine", "concurrence", "iterator", "guard"])
    if kind == "machine":
        count = rng.randint(1, 3)
        states = {}
        for i in range(count):
            state, outcomes = _state(rng, depth + 1)
            after = f"S{i + 1}" if i + 1 < count else "done"
            state["transitions"] = {outcome: after for outcome in outcomes}
            states[f"S{i}"] = state
        return {"state_machine": {"outcomes": ["done"], "states": states}}, ("done",)
    if kind == "concurrence":
        states = {f"C{i}": _state(rng, depth + 1)[0] for i in range(rng.randint(2, 3))}
        wait = rng.choice(["all", "any", "match"])
        spec: dict[str, Any] = {"outcomes": ["done"], "default_outcome": "done", "wait": wait}
        if wait == "match":
            states["C0"] = {"wait": {"seconds": 1.5}}
            spec["outcome_map"] = {"done": {"C0": "done"}}
        return {"concurrence": {**spec, "states": states}}, ("done",)
    if kind == "iterator":
        inner, outcomes = _state(rng, depth + 1)
        iterate = {
            "items": rng.randint(1, 3),
            "continue_on": list(outcomes),
            "state": {"IT": inner},
        }
        return {"iterator": iterate}, ("done",)
    inner, outcomes = _state(rng, depth + 1)
    guard = {
        "state": {"G": inner},
        "timer_s": rng.choice([None, 1.0, 2.5, 9.0]),
        "keywords": ["stop"],
        "touch": ["head"],
        "outcome": "fired",
    }
    return {"guard": guard}, (*outcomes, "fired")


OP_WEIGHTS = {
    "step": 60,
    "same": 2,
    "robot": 3,
    "pause": 1,
    "resume": 1,
    "stop": 0.5,
    "keyword": 0.5,
    "touch": 0.5,
    "high": 1,
    "drop": 1,
    "fault": 0.5,
}


def _random_op(rng: random.Random) -> tuple[str, Any]:
    op = rng.choices(list(OP_WEIGHTS), list(OP_WEIGHTS.values()))[0]
    if op in ("step", "robot"):
        return op, rng.choice([0.05, 0.25, 0.5, 0.5, 0.5, 1.0, 1.7, 3.0])
    if op == "high":
        return op, rng.choice(CHANNELS)
    if op == "fault":
        return op, (rng.choice([*CHANNELS, "*"]), rng.choice([None, "fail", "hang", "stall"]))
    return op, None


def _do(bench: Bench, activity: Activity, op: str, arg: Any) -> None:
    """One thing happening to the activity, its robot or its arbiter."""
    if op in ("step", "robot"):
        bench.now += timedelta(seconds=arg)
        bench.expression.update(bench.now)
        if op == "step":
            activity.tick(bench.now)
    elif op == "same":  # a second tick at the same time (an urgent one)
        activity.tick(bench.now)
    elif op == "pause":
        activity.pause(bench.now)
    elif op == "resume":
        activity.resume(bench.now)
    elif op == "stop":
        activity.preempt(bench.now, limit_s=5.0)
    elif op == "keyword":
        activity.deliver(Speech(text="please stop", confidence=0.9))
    elif op == "touch":
        activity.deliver(Touch(part="head", kind="tap"))
    elif op == "high":  # a dialog's sentence takes the channel: the activity's is queued again
        args = {"text": "a dialog speaks here"}
        bench.expression.request("dialog", arg, "say", args, bench.now, Priority.HIGH)
    elif op == "drop":
        bench.expression.interrupt_source("dialog", bench.now)
    else:
        bench.robot.set_fault(*arg)


@settings(max_examples=150, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_random_machines_do_asleep_what_they_do_awake(seed: int, tmp_path_factory: Any) -> None:
    """Random nesting, robot faults, a dialog taking channels, uneven and repeated ticks."""
    rng = random.Random(seed)
    root, outcomes = _state(rng, 0)
    root["transitions"] = {outcome: "done" for outcome in outcomes}
    spec = {"name": "fuzz", "outcomes": ["done"], "states": {"TOP": root}}
    directory = write_behaviors(tmp_path_factory.mktemp("fuzz"), {"fuzz": yaml.safe_dump(spec)})
    library = BehaviorLibrary.load(Path(directory))
    sleeping, awake = Bench(library, seed=seed % 1000), Bench(library, seed=seed % 1000)
    asleep = sleeping.start(sleeping.create("fuzz"))
    ticking = awake.start(_awake(awake.create("fuzz")))
    for op, arg in [*(_random_op(rng) for _ in range(120)), *[("step", 1.0)] * 30]:
        _do(sleeping, asleep, op, arg)
        _do(awake, ticking, op, arg)
        assert _trace(sleeping, asleep) == _trace(awake, ticking), (op, arg)
    assert asleep.result == ticking.result


def _states(node: Node) -> list[Node]:
    return [node, *(state for child in node.children() for state in _states(child))]
