"""Running one behavior on the simulated Mini and a virtual clock (``dms behavior step|run``).

:class:`BehaviorRun` ticks an activity at 2 Hz on a :class:`~dms.kernel.clock.VirtualClock`
over the robot it is given (``dms behavior`` passes the simulated Mini: the composition
root, dms/cli.py, wires it; activities never import ``sim``), and reports each state
entered with what changed in the userdata and the robot commands since the last
report, as ROS Commander lets its user step through a behavior one node at a time.
"""

from __future__ import annotations

import json
import random
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from activities.activity import Activity, ActivityStatus
from activities.blocks import Ask, WaitEvent
from activities.context import ActivityContext
from activities.engine import Event, Node
from activities.library import BehaviorLibrary
from activities.spec import BehaviorSpec
from dms.kernel.clock import VirtualClock
from dms.kernel.expression import ExpressionArbiter
from dms.kernel.messages import RobotCommand, ScreenChoice, Speech, Touch
from dms.kernel.ports import RobotPort

TICK_S = 0.5
VALUE_CHARS = 100
"""A changed userdata value longer than this (as JSON) is shown cut, with its length."""


@dataclass
class Step:
    """What happened up to the next state change."""

    t: float
    path: str
    status: ActivityStatus
    userdata: dict[str, Any]
    commands: list[RobotCommand] = field(default_factory=list)
    changed: dict[str, Any] = field(default_factory=dict)
    """The userdata keys set or changed since the last step."""
    removed: list[str] = field(default_factory=list)

    def lines(self) -> list[str]:
        out = [f"[{self.t:7.1f}s] {self.status.value:9} {self.path or '-'}"]
        for key, value in self.changed.items():
            out.append(f"  userdata.{key} = {_short(value)}")
        out.extend(f"  userdata.{key} removed" for key in self.removed)
        for command in self.commands:
            args = json.dumps(command.args, ensure_ascii=False)
            out.append(f"  robot: {command.id} {command.channel}.{command.action} {args}")
        return out


def _short(value: Any) -> str:
    text = json.dumps(value, default=str, ensure_ascii=False)
    if len(text) <= VALUE_CHARS:
        return text
    return f"{text[: VALUE_CHARS - 1]}… ({len(text)} characters)"


def parse_input(line: str) -> Event | None:
    """``touch:PART``, ``screen:CHOICE``, or anything else as speech; empty: nothing."""
    text = line.strip()
    if not text:
        return None
    if text.startswith("touch:"):
        part = text[len("touch:") :].strip()
        return Touch.model_validate({"part": part, "kind": "tap"})
    if text.startswith("screen:"):
        return ScreenChoice(choice=text[len("screen:") :].strip() or " ")
    return Speech(text=text, confidence=0.9)


class BehaviorRun:
    """One behavior on the given robot (the simulated Mini), advanced state by state."""

    def __init__(
        self,
        library: BehaviorLibrary,
        spec: BehaviorSpec,
        robot: RobotPort,
        user: Mapping[str, Any] | None = None,
        args: Mapping[str, Any] | None = None,
        seed: int = 0,
    ) -> None:
        self.clock = VirtualClock()
        self.start = self.clock.now()
        self.robot = robot
        self.commands: list[RobotCommand] = []
        self.expression = ExpressionArbiter(self.robot, self.commands.append)
        self.profile: dict[str, Any] = dict(user or {})
        params = {"user": self.profile, "robot": {"battery": 80}, "env": {}}
        ctx = ActivityContext(
            expression=self.expression,
            source=f"activity:{spec.name}",
            params=lambda: {**params, "env": {"time": self.clock.now().hour}},
            rng=random.Random(seed),
            set_user_param=self.profile.__setitem__,
        )
        self.activity: Activity = library.create(spec.name, ctx, args or {})
        self._reported = 0
        self._userdata: dict[str, Any] = {}

    @property
    def t(self) -> float:
        return (self.clock.now() - self.start).total_seconds()

    @property
    def awaiting_answer(self) -> bool:
        """A question or an event wait is active: the user's turn (``step`` waits)."""
        return any(isinstance(node, Ask | WaitEvent) for node in _active_leaves(self.activity.root))

    def _step(self) -> Step:
        new = self.commands[self._reported :]
        self._reported = len(self.commands)
        activity = self.activity
        userdata = dict(activity.userdata)
        changed = {
            key: value
            for key, value in userdata.items()
            if key not in self._userdata or self._userdata[key] != value
        }
        removed = [key for key in self._userdata if key not in userdata]
        self._userdata = {key: _copy(value) for key, value in userdata.items()}
        return Step(
            self.t,
            activity.state_path,
            activity.status or ActivityStatus.RUNNING,
            userdata,
            list(new),
            changed,
            removed,
        )

    def begin(self) -> Step:
        self.activity.start(self.clock.now())
        return self._step()

    def deliver(self, event: Event) -> bool:
        return self.activity.deliver(event)

    def next_state(self, max_s: float = 3600.0) -> Step:
        """Tick until the active state path changes, a question is asked again (a wrong
        answer, the same state), or the activity ends."""
        before = self.activity.state_path
        sent = len(self.commands)
        limit = self.t + max_s
        while not self.activity.finished and self.t < limit:
            now = self.clock.advance(TICK_S)
            self.expression.update(now)
            self.activity.tick(now)
            if self.activity.state_path != before:
                break
            if len(self.commands) > sent and self.awaiting_answer:
                break
        if not self.activity.finished and self.t >= limit:
            self.activity.cancel(self.clock.now())
        return self._step()

    def run(
        self,
        report: Callable[[Step], None],
        answers: list[str] | None = None,
        max_s: float = 3600.0,
    ) -> Activity:
        """Run to the end (or cancel after ``max_s``), answering questions from ``answers``."""
        pending = list(answers or [])

        def answer(step: Step) -> None:
            asked = any(
                c.channel == "speech" and "?" in str(c.args.get("text", "")) for c in step.commands
            )
            if pending and asked:
                event = parse_input(pending.pop(0))
                if event is not None:
                    self.deliver(event)

        first = self.begin()
        report(first)
        answer(first)
        while not self.activity.finished:
            step = self.next_state(max_s=max(0.0, max_s - self.t))
            report(step)
            answer(step)
        return self.activity


def _active_leaves(node: Node) -> list[Node]:
    children = node.active_children()
    if not children:
        return [node]
    return [leaf for child in children for leaf in _active_leaves(child)]


def _copy(value: Any) -> Any:
    """A copy deep enough to see a list or dict changed in place by the next state."""
    if isinstance(value, dict):
        return {key: _copy(item) for key, item in value.items()}
    if isinstance(value, list):
        return [_copy(item) for item in value]
    return value
