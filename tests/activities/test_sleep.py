"""A waiting machine sleeps (issue 14): the ticks it skips change nothing.

After a tick that changed no status, the activity asks its active states what they
wait for (:class:`activities.engine.Wake`) and skips its ticks until that moves or
something reaches it from outside. Each test runs the same activity twice, once with
sleeping and once without (its root never says it can sleep), and compares what they
did after every step: the same states at the same ticks, the same commands.
"""

from __future__ import annotations

from datetime import timedelta
from typing import Any

from hypothesis import given, settings
from hypothesis import strategies as st

from activities import Activity, ActivityStatus, BehaviorLibrary
from activities.engine import Node
from dms.kernel.messages import ScreenChoice, Speech, Touch
from tests.activities.conftest import Bench

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
    for never_sleeps in (False, True):
        bench: Bench = make({"waiting": WAITING})
        activity = bench.create("waiting")
        if never_sleeps:
            _awake(activity)
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


def _states(node: Node) -> list[Node]:
    return [node, *(state for child in node.children() for state in _states(child))]
