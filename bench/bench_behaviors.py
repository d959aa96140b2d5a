"""Cost per tick and per state transition of a three-level machine, beside py_trees;
and of a flat two-state loop, beside py_trees and SMACH.

Both sides run the same shape: three nested containers (state machines here,
memory Sequences in py_trees) around two leaves; each leaf runs for ``HOLD`` ticks
and then finishes, so the machine alternates between ticks that only run and ticks
that change state. A pure "running" measurement ticks a leaf that never finishes.
Prints one JSON object with nanoseconds per tick and per transition for each side
and the ratios (ours / py_trees; at most 1 is the goal).

The flat loop (``flat_*``) is the shape SMACH is measured on: one machine of two
states, ``A -done-> B -done-> A``, each finishing as soon as it runs, so every step is
a transition (here a tick follows up to ``MAX_STEPS_PER_TICK`` of them, as SMACH's
``execute`` follows them in its loop; SMACH's ends when a state counts to the last
one). py_trees runs a memory Sequence of the two leaves (two transitions a tick). The
sides take turns, ``--rounds`` times; a figure is the median of its rounds, a ratio
the median of the rounds' own ratios (the machine is shared: its load moves between
rounds, less within one). ``--instructions`` also counts the instructions a
transition executes on each side (valgrind's cachegrind: the difference of two runs
of different lengths), which the load does not move.

SMACH is not on PyPI: it runs from its source, given with ``--smach`` (a checkout of
github.com/ros/executive_smach, the folder of its ``smach`` package, or the
repository's git directory, read with ``git archive``). Its loggers are silenced (by
default each transition prints a line). Without ``--smach`` its figures are null.

    .venv/bin/python bench/bench_behaviors.py [--quick] [--smach PATH] [--instructions]
"""

from __future__ import annotations

import argparse
import importlib
import io
import json
import os
import random
import re
import shutil
import statistics
import subprocess
import sys
import tarfile
import tempfile
import time
import warnings
from collections.abc import Callable
from datetime import UTC, datetime
from pathlib import Path
from types import ModuleType
from typing import Any

import py_trees

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from activities.containers import StateMachine
from activities.context import ActivityContext
from activities.engine import MAX_STEPS_PER_TICK, Node, Runtime, Status
from dms.kernel.expression import ExpressionArbiter
from sim.robot import SimRobot

TICKS = 200_000
HOLD = 1
FLAT_TRANSITIONS = 200_000
"""Transitions in one round of the flat loop, each side."""
FLAT_ROUNDS = 15
COUNTED = (20_000, 120_000)
"""The two lengths of the flat loop whose difference in instructions is counted."""
NOW = datetime(2026, 11, 23, 9, 0, tzinfo=UTC)
REFS = re.compile(r"I\s+refs:\s+([\d,]+)")


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


def runtime() -> Runtime:
    return Runtime(
        ActivityContext(
            expression=ExpressionArbiter(SimRobot(), lambda _c: None), rng=random.Random(0)
        ),
        {},
    )


def ours(hold: int, ticks: int) -> tuple[float, int]:
    rt = runtime()
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
    rt = runtime()
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


def flat_py_trees(transitions: int) -> tuple[float, int]:
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


def load_smach(source: Path) -> tuple[ModuleType, str | None]:
    """SMACH's ``smach`` package from ``source`` (see the module's docstring), its
    loggers silenced, and the commit it was taken from (None for a bare folder)."""
    if (source / "HEAD").is_file() and (source / "objects").is_dir():
        git = ["git", f"--git-dir={source}"]
        archive = subprocess.run([*git, "archive", "HEAD", "smach/smach"], capture_output=True)
        if archive.returncode != 0:
            raise SystemExit(f"bench_behaviors: --smach {source}: git archive found no smach/smach")
        with tempfile.TemporaryDirectory(prefix="bench-smach-") as folder:
            with tarfile.open(fileobj=io.BytesIO(archive.stdout)) as tar:
                tar.extractall(folder, filter="data")
            smach = _import_smach(Path(folder) / "smach")  # imports all its modules at once
        return smach, _head(git)
    if (source / "smach" / "smach" / "__init__.py").is_file():
        smach = _import_smach(source / "smach")
        return smach, _head(["git", "-C", str(source)]) if (source / ".git").exists() else None
    if (source / "smach" / "__init__.py").is_file():
        return _import_smach(source), None
    raise SystemExit(
        f"bench_behaviors: --smach {source}: no smach package there "
        "(give a checkout of ros/executive_smach or its git directory)"
    )


def _head(git: list[str]) -> str | None:
    head = subprocess.run([*git, "rev-parse", "HEAD"], capture_output=True, text=True)
    return head.stdout.strip() if head.returncode == 0 else None


def _import_smach(folder: Path) -> ModuleType:
    sys.path.insert(0, str(folder))
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", SyntaxWarning)  # an ``is not`` on a literal in it
            smach = importlib.import_module("smach")
    finally:
        sys.path.remove(str(folder))

    def quiet(_message: str) -> None:
        return None

    smach.set_loggers(quiet, quiet, quiet, quiet)
    return smach


def flat_smach(smach: ModuleType, transitions: int) -> tuple[float, int]:
    """SMACH's flat loop: two states that return ``done`` at once, the last ``stop``."""
    counter = [0]

    class Flip(smach.State):  # type: ignore[name-defined,misc]
        def __init__(self) -> None:
            super().__init__(outcomes=["done", "stop"])
            self.counter = counter

        def execute(self, _userdata: Any) -> str:
            self.counter[0] += 1
            if self.counter[0] == transitions:
                return "stop"
            return "done"

    loop = smach.StateMachine(outcomes=["stop"])
    with loop:
        smach.StateMachine.add("A", Flip(), transitions={"done": "B", "stop": "stop"})
        smach.StateMachine.add("B", Flip(), transitions={"done": "A", "stop": "stop"})
    start = time.perf_counter()
    loop.execute()
    elapsed = time.perf_counter() - start
    return elapsed, counter[0]


def flat_rounds(
    sides: dict[str, Callable[[int], tuple[float, int]]], transitions: int, rounds: int
) -> dict[str, list[float]]:
    """Nanoseconds per transition of each side in each round, the sides taking turns."""
    costs: dict[str, list[float]] = {name: [] for name in sides}
    for _ in range(rounds):
        for name, measure in sides.items():
            elapsed, taken = measure(transitions)
            costs[name].append(elapsed / taken * 1e9)
    return costs


def count(side: str, transitions: int, smach_source: Path | None) -> tuple[int, int]:
    """Instructions of a run of this file that takes ``transitions`` on ``side``
    (valgrind's cachegrind), and the transitions it took."""
    command = [
        "valgrind",
        "--tool=cachegrind",
        "--cache-sim=no",
        "--cachegrind-out-file=/dev/null",
        sys.executable,
        __file__,
        "--count",
        side,
        str(transitions),
    ]
    if smach_source is not None:
        command += ["--smach", str(smach_source)]
    done = subprocess.run(
        command,
        capture_output=True,
        text=True,
        check=False,
        env={**os.environ, "PYTHONHASHSEED": "0"},
    )
    found = REFS.search(done.stderr)
    if done.returncode != 0 or found is None:
        last = (done.stderr.strip().splitlines() or ["no output"])[-1]
        raise SystemExit(f"bench_behaviors: the counted {side} run failed: {last}")
    return int(found.group(1).replace(",", "")), int(done.stdout.split()[-1])


def instructions_per_transition(side: str, scale: int, smach_source: Path | None) -> float:
    """The difference of two counted runs over the difference of their transitions:
    what the imports and the setup cost cancels out."""
    short, long = (count(side, n // scale, smach_source) for n in COUNTED)
    return (long[0] - short[0]) / (long[1] - short[1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a hundredth of the ticks (smoke)")
    parser.add_argument(
        "--smach",
        type=Path,
        help="SMACH source: a checkout of ros/executive_smach, or its git dir",
    )
    parser.add_argument(
        "--rounds", type=int, default=FLAT_ROUNDS, help=f"flat-loop rounds (default {FLAT_ROUNDS})"
    )
    parser.add_argument(
        "--instructions",
        action="store_true",
        help="also count the instructions of a flat transition (needs valgrind)",
    )
    parser.add_argument("--count", nargs=2, metavar=("SIDE", "N"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.rounds < 1:
        parser.error("--rounds: must be at least 1")
    if args.smach is not None and not args.smach.is_dir():
        parser.error(f"--smach: {args.smach} is not a directory")
    smach, smach_commit = load_smach(args.smach) if args.smach is not None else (None, None)
    sides: dict[str, Callable[[int], tuple[float, int]]] = {
        "ours": flat_ours,
        "py_trees": flat_py_trees,
    }
    if smach is not None:
        sides["smach"] = lambda transitions: flat_smach(smach, transitions)
    if args.count is not None:  # one counted run, under valgrind (``count``)
        side, transitions = args.count
        if side not in sides or not transitions.isdigit():
            parser.error(f"--count: a side of {sorted(sides)} and a number of transitions")
        print("transitions", sides[side](int(transitions))[1])
        return
    quick = args.quick
    scale = 100 if quick else 1
    ticks = TICKS // scale
    figures: dict[str, Any] = {"ticks": ticks, "quick": quick}
    our_run, _ = ours(-1, ticks)
    their_run, _ = theirs(-1, ticks)
    our_mixed, our_transitions = ours(HOLD, ticks)
    their_mixed, their_transitions = theirs(HOLD, ticks)
    figures["ours_ns_per_running_tick"] = round(our_run / ticks * 1e9, 1)
    figures["py_trees_ns_per_running_tick"] = round(their_run / ticks * 1e9, 1)
    figures["ours_transitions"] = our_transitions
    figures["py_trees_transitions"] = their_transitions
    figures["ours_ns_per_transition"] = round(our_mixed / our_transitions * 1e9, 1)
    figures["py_trees_ns_per_transition"] = round(their_mixed / their_transitions * 1e9, 1)
    figures["tick_ratio"] = round(our_run / their_run, 3)
    figures["transition_ratio"] = round(
        (our_mixed / our_transitions) / (their_mixed / their_transitions), 3
    )
    rounds = min(args.rounds, 3) if quick else args.rounds
    costs = flat_rounds(sides, FLAT_TRANSITIONS // scale, rounds)
    figures["smach_commit"] = smach_commit
    figures["flat_transitions"] = FLAT_TRANSITIONS // scale
    figures["flat_rounds"] = rounds
    for name in ("ours", "py_trees", "smach"):
        cost = costs.get(name)
        figures[f"flat_{name}_ns_per_transition"] = (
            round(statistics.median(cost), 1) if cost else None
        )
    for name in ("py_trees", "smach"):
        paired = costs.get(name)
        figures[f"flat_ratio_to_{name}"] = (
            round(statistics.median(o / t for o, t in zip(costs["ours"], paired, strict=True)), 3)
            if paired
            else None
        )
    if args.instructions:
        if shutil.which("valgrind") is None:
            figures["flat_instructions"] = "skipped: valgrind not found (apt install valgrind)"
        else:
            for name in sides:
                per = instructions_per_transition(name, scale, args.smach)
                figures[f"flat_{name}_instructions_per_transition"] = round(per)
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
