"""Cost per tick and per state transition of a three-level machine, beside py_trees;
and of a flat two-state loop, beside py_trees and SMACH.

Both sides run the same shape: three nested containers (state machines here,
memory Sequences in py_trees) around two leaves; each leaf runs for ``HOLD`` ticks
and then finishes, so the machine alternates between ticks that only run and ticks
that change state. A pure "running" measurement ticks a leaf that never finishes.
Prints one JSON object with nanoseconds per tick and per transition for each side
and the ratios (ours / py_trees; at most 1 is the goal).

The flat loop (``flat_*``) is the shape SMACH was measured on: one machine of
two states, ``A -done-> B -done-> A``, each finishing as soon as it runs, so every
step is a transition (here a tick follows up to ``MAX_STEPS_PER_TICK`` of them, as
SMACH's ``execute`` follows them in its loop). py_trees runs a memory Sequence of the
two leaves (two transitions a tick). SMACH is not on PyPI: its figure is the one
measured outside the project (``SMACH_FLAT_NS``, 2.5 µs a transition; dms was 2.1 µs
there), printed beside ours for the ratio.

    .venv/bin/python bench/bench_behaviors.py [--quick]
"""

from __future__ import annotations

import argparse
import json
import random
import sys
import time
from collections.abc import Callable
from datetime import UTC, datetime
from pathlib import Path

import py_trees

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from activities.containers import StateMachine
from activities.context import ActivityContext
from activities.engine import MAX_STEPS_PER_TICK, Node, Runtime, Status
from dms.kernel.expression import ExpressionArbiter
from sim.robot import SimRobot

TICKS = 200_000
HOLD = 1
FLAT_TRANSITIONS = 1_000_000
SMACH_FLAT_NS = 2500.0
"""SMACH's cost per transition of the flat two-state loop, measured outside the project."""
NOW = datetime(2026, 11, 23, 9, 0, tzinfo=UTC)


class Blink(Node):
    """Runs ``hold`` ticks, then finishes ``done`` (``hold`` < 0: runs forever)."""

    def __init__(self, name: str, rt: Runtime, hold: int, counter: list[int]) -> None:
        super().__init__(name, ("done",), rt)
        self.hold = hold
        self.counter = counter
        self.left = 0

    def initialise(self, now: datetime) -> None:
        self.left = self.hold

    def update(self, now: datetime) -> Status:
        if self.left == 0:
            self.counter[0] += 1
            return Status.DONE
        self.left -= 1
        return Status.RUNNING


def ours(hold: int, ticks: int) -> tuple[float, int]:
    robot = SimRobot()
    ctx = ActivityContext(
        expression=ExpressionArbiter(robot, lambda _c: None), rng=random.Random(0)
    )
    rt = Runtime(ctx, {})
    counter = [0]

    def level3() -> StateMachine:
        leaves = {"A": Blink("A", rt, hold, counter), "B": Blink("B", rt, hold, counter)}
        return StateMachine(
            "L3", ["done"], rt, leaves, {"A": {"done": "B"}, "B": {"done": "done"}}, "A"
        )

    level2 = StateMachine("L2", ["done"], rt, {"L3": level3()}, {"L3": {"done": "done"}}, "L3")
    root = StateMachine("L1", ["done"], rt, {"L2": level2}, {"L2": {"done": "L2"}}, "L2")
    root.bind({})
    tick = root.tick
    start = time.perf_counter()
    for _ in range(ticks):
        tick(NOW)
    elapsed = time.perf_counter() - start
    return elapsed, counter[0]


class PyBlink(py_trees.behaviour.Behaviour):
    def __init__(self, name: str, hold: int, counter: list[int]) -> None:
        super().__init__(name)
        self.hold = hold
        self.counter = counter
        self.left = 0

    def initialise(self) -> None:
        self.left = self.hold

    def update(self) -> py_trees.common.Status:
        if self.left == 0:
            self.counter[0] += 1
            return py_trees.common.Status.SUCCESS
        self.left -= 1
        return py_trees.common.Status.RUNNING


def theirs(hold: int, ticks: int) -> tuple[float, int]:
    counter = [0]
    level3 = py_trees.composites.Sequence("L3", memory=True)
    level3.add_children([PyBlink("A", hold, counter), PyBlink("B", hold, counter)])
    level2 = py_trees.composites.Sequence("L2", memory=True)
    level2.add_child(level3)
    root = py_trees.composites.Sequence("L1", memory=True)
    root.add_child(level2)
    tree = py_trees.trees.BehaviourTree(root)
    tick = tree.root.tick_once
    start = time.perf_counter()
    for _ in range(ticks):
        tick()
    elapsed = time.perf_counter() - start
    return elapsed, counter[0]


def flat_ours(transitions: int) -> tuple[float, int]:
    """The flat two-state loop: seconds for about ``transitions`` transitions."""
    rt = Runtime(
        ActivityContext(
            expression=ExpressionArbiter(SimRobot(), lambda _c: None), rng=random.Random(0)
        ),
        {},
    )
    counter = [0]
    states: dict[str, Node] = {"A": Blink("A", rt, 0, counter), "B": Blink("B", rt, 0, counter)}
    loop = StateMachine("FLAT", ["done"], rt, states, {"A": {"done": "B"}, "B": {"done": "A"}}, "A")
    loop.bind({})
    tick = loop.tick
    ticks = transitions // MAX_STEPS_PER_TICK
    start = time.perf_counter()
    for _ in range(ticks):
        tick(NOW)
    elapsed = time.perf_counter() - start
    return elapsed, loop.transitions_taken


def flat_theirs(transitions: int) -> tuple[float, int]:
    """py_trees' flat loop: a memory Sequence of two leaves that succeed at once."""
    counter = [0]
    root = py_trees.composites.Sequence("FLAT", memory=True)
    root.add_children([PyBlink("A", 0, counter), PyBlink("B", 0, counter)])
    tree = py_trees.trees.BehaviourTree(root)
    tick = tree.root.tick_once
    start = time.perf_counter()
    for _ in range(transitions // 2):
        tick()
    elapsed = time.perf_counter() - start
    return elapsed, counter[0]


def best_of(runs: int, measure: Callable[[], tuple[float, int]]) -> tuple[float, int]:
    """The fastest of ``runs`` measurements (the machine is shared: the rest is noise)."""
    return min((measure() for _ in range(runs)), key=lambda result: result[0] / result[1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a hundredth of the ticks (smoke)")
    quick = parser.parse_args().quick
    ticks = TICKS // 100 if quick else TICKS
    flat = FLAT_TRANSITIONS // 100 if quick else FLAT_TRANSITIONS
    figures: dict[str, float | int | bool] = {"ticks": ticks, "quick": quick}
    our_run, _ = ours(-1, ticks)
    their_run, _ = theirs(-1, ticks)
    our_mixed, our_transitions = ours(HOLD, ticks)
    their_mixed, their_transitions = theirs(HOLD, ticks)
    figures["ours_ns_per_running_tick"] = round(our_run / TICKS * 1e9, 1)
    figures["py_trees_ns_per_running_tick"] = round(their_run / TICKS * 1e9, 1)
    figures["ours_transitions"] = our_transitions
    figures["py_trees_transitions"] = their_transitions
    figures["ours_ns_per_transition"] = round(our_mixed / our_transitions * 1e9, 1)
    figures["py_trees_ns_per_transition"] = round(their_mixed / their_transitions * 1e9, 1)
    figures["tick_ratio"] = round(our_run / their_run, 3)
    figures["transition_ratio"] = round(
        (our_mixed / our_transitions) / (their_mixed / their_transitions), 3
    )
    flat_s, flat_n = best_of(5, lambda: flat_ours(flat))
    py_flat_s, py_flat_n = best_of(5, lambda: flat_theirs(flat))
    flat_ns = flat_s / flat_n * 1e9
    py_flat_ns = py_flat_s / py_flat_n * 1e9
    figures["flat_transitions"] = flat_n
    figures["flat_ours_ns_per_transition"] = round(flat_ns, 1)
    figures["flat_py_trees_ns_per_transition"] = round(py_flat_ns, 1)
    figures["flat_smach_ns_per_transition"] = SMACH_FLAT_NS
    figures["flat_ratio_to_smach"] = round(flat_ns / SMACH_FLAT_NS, 3)
    figures["flat_ratio_to_py_trees"] = round(flat_ns / py_flat_ns, 3)
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
