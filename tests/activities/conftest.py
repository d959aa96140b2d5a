"""Shared fixtures: a simulated robot, an arbiter and activities on a virtual clock."""

from __future__ import annotations

import random
import textwrap
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

import pytest

from activities import Activity, ActivityContext, ActivityStatus, BehaviorLibrary
from dms.kernel.expression import ExpressionArbiter
from dms.kernel.messages import RobotCommand
from sim.robot import SimRobot

T0 = datetime(2026, 11, 23, 9, 0, tzinfo=UTC)


@dataclass
class FakeResult:
    activate: list[str]


@dataclass
class FakeRules:
    """A rule evaluator answering from a table; records what was asked."""

    table: dict[str, list[str]] = field(default_factory=dict)
    asked: list[str] = field(default_factory=list)

    def evaluate(
        self, component: str, params: Mapping[str, Mapping[str, Any]]
    ) -> FakeResult | None:
        self.asked.append(component)
        if component not in self.table:
            return None
        return FakeResult(list(self.table[component]))


class Bench:
    """A robot, an arbiter and a clock; builds and ticks activities."""

    def __init__(self, library: BehaviorLibrary | None = None, seed: int = 0) -> None:
        self.now = T0
        self.robot = SimRobot(rng_seed=seed)
        self.commands: list[RobotCommand] = []
        self.expression = ExpressionArbiter(self.robot, self.commands.append, ack_timeout_s=5.0)
        self.library = library
        self.user: dict[str, Any] = {"name": "Ana"}
        self.robot_params: dict[str, Any] = {"battery": 55}
        self.stored: dict[str, Any] = {}
        self.rules: FakeRules | None = None
        self.rng = random.Random(seed)

    def context(self, name: str = "test") -> ActivityContext:
        return ActivityContext(
            expression=self.expression,
            source=f"activity:{name}",
            params=lambda: {"user": self.user, "robot": self.robot_params, "env": {"time": 9}},
            rules=self.rules,
            rng=self.rng,
            set_user_param=self.stored.__setitem__,
        )

    def create(self, name: str, args: Mapping[str, Any] | None = None) -> Activity:
        assert self.library is not None
        return self.library.create(name, self.context(name), args or {})

    def start(self, activity: Activity) -> Activity:
        activity.start(self.now)
        return activity

    def advance(self, activity: Activity | None, seconds: float, step: float = 0.5) -> None:
        end = self.now + timedelta(seconds=seconds)
        while self.now < end:
            self.now += timedelta(seconds=step)
            self.expression.update(self.now)
            if activity is not None:
                activity.tick(self.now)

    def run_until(
        self, activity: Activity, predicate: Any, limit_s: float = 3600.0, step: float = 0.5
    ) -> None:
        """Tick until ``predicate()`` holds; fail the test if it never does."""
        end = self.now + timedelta(seconds=limit_s)
        while not predicate():
            assert self.now < end, f"not reached in {limit_s} s (at {activity.state_path!r})"
            self.now += timedelta(seconds=step)
            self.expression.update(self.now)
            activity.tick(self.now)

    def finish(self, activity: Activity, limit_s: float = 3600.0) -> ActivityStatus:
        self.run_until(activity, lambda: activity.finished, limit_s)
        assert activity.status is not None
        return activity.status

    def said(self) -> list[str]:
        return [str(c.args.get("text")) for c in self.commands if c.channel == "speech"]

    def last_said(self) -> str:
        return self.said()[-1]


def write_behaviors(directory: Path, files: Mapping[str, str]) -> Path:
    directory.mkdir(parents=True, exist_ok=True)
    for name, text in files.items():
        (directory / f"{name}.yaml").write_text(textwrap.dedent(text).lstrip())
    return directory


@pytest.fixture
def shipped() -> BehaviorLibrary:
    return BehaviorLibrary.load()


@pytest.fixture
def bench(shipped: BehaviorLibrary) -> Bench:
    return Bench(shipped)


@pytest.fixture
def make(tmp_path: Path) -> Iterator[Any]:
    """Build a Bench over behaviors written from YAML text."""

    def build(files: Mapping[str, str]) -> Bench:
        library = BehaviorLibrary.load(write_behaviors(tmp_path / "behaviors", files))
        return Bench(library)

    yield build
