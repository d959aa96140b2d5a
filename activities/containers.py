"""SMACH's containers: states that hold userdata and run the states inside them.

- a :class:`StateMachine` follows ``transitions`` from each state's outcome to the
  next state or to one of its own outcomes;
- a :class:`Concurrence` ticks its states together and ends by its ``outcome_map``
  (or ``default_outcome`` when all are done and no entry matched);
- an :class:`Iterator` runs its state once per item;
- a :class:`Guard` (ROS Commander's tactile guard) stops what it contains when a
  touch, a keyword or a timer fires.

Each passes a preemption request on to its active states (:meth:`Node.forward_preempt`)
and services the ``preempted`` outcome where its transitions or maps name it.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, MutableMapping, Sequence
from dataclasses import dataclass
from datetime import datetime, timedelta
from enum import Enum
from typing import Any

from activities.engine import (
    MAX_STEPS_PER_TICK,
    PREEMPTED,
    Event,
    Io,
    Node,
    Runtime,
    Status,
    Wake,
)
from dms.kernel.messages import ScreenChoice, Touch


class Container(Node):
    """A state that holds userdata for the states it contains."""

    is_container = True

    def __init__(
        self,
        name: str,
        outcomes: Sequence[str],
        rt: Runtime,
        io: Io | None = None,
        userdata: Mapping[str, Any] | None = None,
    ):
        super().__init__(name, outcomes, rt, io)
        self.initial_userdata = dict(userdata or {})
        self.data: MutableMapping[str, Any] = {}

    @property
    def shares_userdata(self) -> bool:
        """Without declared keys a nested container works on its parent's userdata."""
        return not self.io.input_keys and not self.io.output_keys and not self.io.remapping

    def initialise(self, now: datetime) -> None:
        if self.shares_userdata:
            target = self.ud
            for key, value in self.initial_userdata.items():
                if key not in target:
                    target[key] = _copy(value)
            self.data = target
        else:
            self.data = {key: _copy(value) for key, value in self.initial_userdata.items()}
            for key in self.io.input_keys:
                if key in self.ud:
                    self.data[key] = self.ud[key]
        self.enter_children(now)

    def enter_children(self, now: datetime) -> None:
        """Bind and reset the states to run first."""

    def terminate(self, now: datetime, new_status: Status) -> None:
        if new_status is Status.DONE and not self.shares_userdata:
            for key in self.io.output_keys:
                if key in self.data:
                    self.ud[key] = self.data[key]


def _copy(value: Any) -> Any:
    if isinstance(value, list):
        return [_copy(v) for v in value]
    if isinstance(value, dict):
        return {k: _copy(v) for k, v in value.items()}
    return value


class StateMachine(Container):
    """States joined by transitions; ends when a transition names one of its outcomes."""

    kind = "state_machine"

    def __init__(
        self,
        name: str,
        outcomes: Sequence[str],
        rt: Runtime,
        states: Mapping[str, Node],
        transitions: Mapping[str, Mapping[str, str]],
        initial: str,
        io: Io | None = None,
        userdata: Mapping[str, Any] | None = None,
    ):
        super().__init__(name, outcomes, rt, io, userdata)
        self.states = dict(states)
        self.transitions = {name: dict(t) for name, t in transitions.items()}
        self.initial = initial
        self.current: Node | None = None
        self.transitions_taken = 0

    def children(self) -> Sequence[Node]:
        return list(self.states.values())

    def active_children(self) -> Sequence[Node]:
        return [self.current] if self.current is not None else []

    def enter_children(self, now: datetime) -> None:
        self._enter(self.states[self.initial])

    def _enter(self, state: Node) -> None:
        state.reset()
        state.bind(self.data)
        self.current = state
        self.rt.epoch += 1

    def forward_preempt(self) -> None:
        if self.current is not None:
            self.current.preempt()

    def wake(self, now: datetime) -> Wake | None:
        current = self.current
        if self._preempt_requested or current is None or current.status is not Status.RUNNING:
            return None
        return current.wake(now)

    def update(self, now: datetime) -> Status:
        steps = MAX_STEPS_PER_TICK
        while steps:  # not a ``range``: one a tick at every level made a running tick 25 % longer
            steps -= 1
            state = self.current
            if state is None:
                return self.fail("no active state")
            status = state.tick(now)
            if status is Status.RUNNING:
                return status
            if status is Status.FAILED:
                return self.fail(f"{state.name}: {state.error}")
            outcome = state.outcome or ""
            target = self.transitions.get(state.name, {}).get(outcome)
            if target is None:
                target = outcome  # an outcome of the container passes through
                if outcome == PREEMPTED:
                    state.status = Status.INVALID  # not serviced here: it climbs
            self.transitions_taken += 1
            if target in self.states:
                self._enter(self.states[target])
                continue
            self.current = None
            self.rt.epoch += 1
            return self.finish(target)
        return Status.RUNNING

    def terminate(self, now: datetime, new_status: Status) -> None:
        super().terminate(now, new_status)
        if new_status is not Status.INVALID:
            self.current = None
            self.rt.epoch += 1

    def describe(self) -> dict[str, Any]:
        out = super().describe()
        out["initial"] = self.initial
        out["transitions"] = {k: dict(v) for k, v in self.transitions.items() if v}
        return out


class ConcurrenceWait(Enum):
    """When a concurrence preempts its other states (SMACH's ``child_termination_cb``)."""

    MATCH = "match"
    """As soon as an entry of the outcome map matches (the callback tests the map)."""
    ALL = "all"
    """Never: every state runs to its end (SMACH's default, no callback)."""
    ANY = "any"
    """As soon as any state ends (the callback returns True)."""


class Concurrence(Container):
    """States ticked together; the ``outcome_map`` decides when and how it ends."""

    kind = "concurrence"

    def __init__(
        self,
        name: str,
        outcomes: Sequence[str],
        rt: Runtime,
        states: Mapping[str, Node],
        outcome_map: Mapping[str, Mapping[str, str]],
        default_outcome: str,
        io: Io | None = None,
        userdata: Mapping[str, Any] | None = None,
        wait: ConcurrenceWait = ConcurrenceWait.MATCH,
    ):
        super().__init__(name, outcomes, rt, io, userdata)
        self.states = dict(states)
        self.outcome_map = {k: dict(v) for k, v in outcome_map.items()}
        self.default_outcome = default_outcome
        self.wait = wait
        self._services = frozenset(
            child
            for wanted in self.outcome_map.values()
            for child, out in wanted.items()
            if out == PREEMPTED
        )
        self._winding_down = False
        """The others were asked to stop (a match, a state ended, or a preemption)."""
        self._preempted = False
        """The concurrence itself was preempted (from above, or a state's climbed)."""

    def children(self) -> Sequence[Node]:
        return list(self.states.values())

    def active_children(self) -> Sequence[Node]:
        return [s for s in self.states.values() if s.status is Status.RUNNING]

    def enter_children(self, now: datetime) -> None:
        self._winding_down = False
        self._preempted = False
        for state in self.states.values():
            state.reset()
            state.bind(self.data)

    def forward_preempt(self) -> None:
        self._preempted = True
        self._wind_down()

    def wake(self, now: datetime) -> Wake | None:
        """All its running states wait (the ended ones stay as they are): with no
        status changed, ``update`` decides as it did."""
        if self._preempt_requested or self._winding_down:
            return None
        waiting = Wake()
        for state in self.states.values():
            if state.status is Status.DONE:
                continue
            wake = state.wake(now) if state.status is Status.RUNNING else None
            if wake is None:
                return None
            waiting.join(wake)
        return waiting

    def _wind_down(self) -> None:
        self._winding_down = True
        for state in self.states.values():
            if state.status is Status.INVALID or state.status is Status.RUNNING:
                state.preempt()

    def _tick_all(self, now: datetime) -> Node | None:
        for state in self.states.values():
            live = state.status is Status.INVALID or state.status is Status.RUNNING
            if live and state.tick(now) is Status.FAILED:
                return state
        return None

    def _match(self) -> str | None:
        for outcome, wanted in self.outcome_map.items():
            if all(
                self.states[child].status is Status.DONE and self.states[child].outcome == out
                for child, out in wanted.items()
            ):
                return outcome
        return None

    def update(self, now: datetime) -> Status:
        """Tick every state; when the wait mode says so, preempt the others (their
        cleanup runs), and once all have ended read the outcome map in order."""
        failed = self._tick_all(now)
        if failed is None and not self._winding_down:
            done = [s for s in self.states.values() if s.status is Status.DONE]
            climbed = any(s.outcome == PREEMPTED and s.name not in self._services for s in done)
            if climbed:
                self._preempted = True
            if (
                climbed
                or (self.wait is ConcurrenceWait.ANY and done)
                or (self.wait is ConcurrenceWait.MATCH and self._match() is not None)
            ):
                self._wind_down()
                failed = self._tick_all(now)
        if failed is not None:
            self._stop_all(now)
            return self.fail(f"{failed.name}: {failed.error}")
        if any(state.status is not Status.DONE for state in self.states.values()):
            return Status.RUNNING
        outcome = self._match()
        if outcome is not None:
            return self.finish(outcome)
        if self._preempted:
            for state in self.states.values():
                state.status = Status.INVALID  # not serviced here: it climbs
            return self.finish(PREEMPTED)
        return self.finish(self.default_outcome)

    def _stop_all(self, now: datetime) -> None:
        for state in self.states.values():
            if state.status is Status.RUNNING:
                state.stop(now)

    def describe(self) -> dict[str, Any]:
        out = super().describe()
        out["outcome_map"] = {k: dict(v) for k, v in self.outcome_map.items()}
        out["default_outcome"] = self.default_outcome
        out["wait"] = self.wait.value
        return out


class Iterator(Container):
    """Runs its state once per item, the item in userdata under ``item_key``."""

    kind = "iterator"

    def __init__(
        self,
        name: str,
        outcomes: Sequence[str],
        rt: Runtime,
        state: Node,
        items: Any,
        item_key: str,
        index_key: str | None,
        continue_on: Sequence[str],
        break_on: Mapping[str, str],
        exhausted: str,
        io: Io | None = None,
        userdata: Mapping[str, Any] | None = None,
    ):
        super().__init__(name, outcomes, rt, io, userdata)
        self.state = state
        self.items_spec = items
        self.item_key = item_key
        self.index_key = index_key
        self.continue_on = frozenset(continue_on)
        self.break_on = dict(break_on)
        self.exhausted = exhausted
        self.items: list[Any] = []
        self.index = 0

    def children(self) -> Sequence[Node]:
        return [self.state]

    def active_children(self) -> Sequence[Node]:
        return [self.state] if self.state.status is Status.RUNNING else []

    def forward_preempt(self) -> None:
        if self.index < len(self.items):
            self.state.preempt()

    def wake(self, now: datetime) -> Wake | None:
        if self._preempt_requested or self.state.status is not Status.RUNNING:
            return None
        return self.state.wake(now)

    def enter_children(self, now: datetime) -> None:
        items = self.rt.render(self.items_spec, self.data)
        if isinstance(items, int) and not isinstance(items, bool):
            items = list(range(1, items + 1))
        self.items = list(items) if isinstance(items, list | tuple) else []
        self.index = 0
        self._next()

    def _next(self) -> None:
        if self.index < len(self.items):
            self.data[self.item_key] = self.items[self.index]
            if self.index_key:
                self.data[self.index_key] = self.index + 1
            self.state.reset()
            self.state.bind(self.data)

    def update(self, now: datetime) -> Status:
        for _ in range(MAX_STEPS_PER_TICK):
            if self.index >= len(self.items):
                return self.finish(self.exhausted)
            status = self.state.tick(now)
            if status is Status.RUNNING:
                return Status.RUNNING
            if status is Status.FAILED:
                return self.fail(f"{self.state.name}: {self.state.error}")
            outcome = self.state.outcome or ""
            if outcome in self.break_on:
                return self.finish(self.break_on[outcome])
            if outcome not in self.continue_on:
                if outcome == PREEMPTED:
                    self.state.status = Status.INVALID  # not serviced here: it climbs
                return self.finish(outcome)
            self.index += 1
            self._next()
        return Status.RUNNING

    def describe(self) -> dict[str, Any]:
        out = super().describe()
        out["index"] = self.index
        out["items"] = len(self.items)
        return out


@dataclass(frozen=True)
class Trigger:
    """What fires a guard: touched parts, spoken keywords, screen choices, a timer."""

    touch: frozenset[str] = frozenset()
    keywords: tuple[str, ...] = ()
    screen: frozenset[str] = frozenset()
    timer_s: float | None = None

    def matches(self, event: Event) -> bool:
        if isinstance(event, Touch):
            return event.part in self.touch
        if isinstance(event, ScreenChoice):
            return event.choice.strip().lower() in self.screen
        spoken = words(event.text)
        return any(words(keyword) in spoken for keyword in self.keywords)


def words(text: str) -> str:
    """Lower-case words between spaces, for whole-word matching of keywords."""
    return " " + " ".join(re.findall(r"[\w']+", text.lower())) + " "


class Guard(Container):
    """Stops what it contains when its trigger fires (ROS Commander's tactile guard)."""

    kind = "guard"

    def __init__(
        self,
        name: str,
        outcomes: Sequence[str],
        rt: Runtime,
        state: Node,
        trigger: Trigger,
        trigger_outcome: str,
        io: Io | None = None,
    ):
        super().__init__(name, outcomes, rt, io)
        self.state = state
        self.trigger = trigger
        self.trigger_outcome = trigger_outcome
        self.fired: str | None = None
        self._deadline: datetime | None = None
        self._remaining: float | None = None

    def children(self) -> Sequence[Node]:
        return [self.state]

    def active_children(self) -> Sequence[Node]:
        return [self.state] if self.state.status is Status.RUNNING else []

    def forward_preempt(self) -> None:
        self.state.preempt()

    def enter_children(self, now: datetime) -> None:
        self.fired = None
        timer = self.trigger.timer_s
        self._deadline = now + timedelta(seconds=timer) if timer is not None else None
        self.state.reset()
        self.state.bind(self.data)

    def wake(self, now: datetime) -> Wake | None:
        """Its state's, and its timer."""
        if self._preempt_requested or self.fired is not None:
            return None
        if self.state.status is not Status.RUNNING:
            return None
        wake = self.state.wake(now)
        return None if wake is None else wake.until(self._deadline)

    def on_event(self, event: Event) -> bool:
        if self.fired is None and self.trigger.matches(event):
            self.fired = type(event).__name__.lower()
            return True
        return False

    def update(self, now: datetime) -> Status:
        if self.fired is None and self._deadline is not None and now >= self._deadline:
            self.fired = "timer"
        if self.fired is not None:
            self.state.stop(now)
            return self.finish(self.trigger_outcome)
        status = self.state.tick(now)
        if status is Status.FAILED:
            return self.fail(f"{self.state.name}: {self.state.error}")
        if status is Status.DONE:
            if self.state.outcome == PREEMPTED:
                self.state.status = Status.INVALID  # a guard never services it: it climbs
            return self.finish(self.state.outcome or "")
        return Status.RUNNING

    def on_pause(self, now: datetime) -> None:
        if self._deadline is not None:
            self._remaining = max(0.0, (self._deadline - now).total_seconds())

    def on_resume(self, now: datetime) -> None:
        if self._remaining is not None:
            self._deadline = now + timedelta(seconds=self._remaining)
            self._remaining = None

    def describe(self) -> dict[str, Any]:
        out = super().describe()
        out["trigger_outcome"] = self.trigger_outcome
        return out
