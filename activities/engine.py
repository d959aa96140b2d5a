"""The tick-based state-machine engine: states, userdata and the containers.

A :class:`Node` is a state with outcomes. The framework owns :meth:`Node.tick`; a
state implements the py_trees-style hooks ``initialise`` (entered), ``update`` (one
tick, never blocks, returns a :class:`Status`) and ``terminate`` (left, with the new
status: ``INVALID`` means it was stopped from outside). On top come SMACH's semantics:

- a :class:`StateMachine` follows ``transitions`` from each state's outcome to the
  next state or to one of its own outcomes;
- userdata: each container holds a dict; a state sees it through a
  :class:`UserdataView` limited to its declared ``input_keys``/``output_keys`` and
  renamed by ``remapping``;
- a :class:`Concurrence` ticks its states together and ends by its ``outcome_map``
  (or ``default_outcome`` when all are done and no entry matched);
- an :class:`Iterator` runs its state once per item;
- a :class:`Guard` (ROS Commander's tactile guard) stops what it contains when a
  touch, a keyword or a timer fires;
- preemption is SMACH's, cooperative and a status, not an exception:
  :meth:`Node.preempt` marks a state; at its next tick a container passes the request
  to its active states, a leaf ends with the outcome ``preempted``. The container
  whose transition (or outcome map, ``continue_on``/``break_on``) names that outcome
  services it and goes on (a cleanup state); one that does not is stopped
  (``INVALID``) and itself ends ``preempted``, so the request climbs. ``stop``
  clears a request that was not serviced;
- pause is history: :meth:`Node.pause` freezes the active states at every depth,
  :meth:`Node.resume` re-enters them and their blocks restart what they were saying;
- a machine that waits sleeps: after a tick that left it running, :meth:`Node.wake`
  tells what the active states wait for (a time, the end of their robot commands);
  until one of those comes, or something reaches the machine from outside, its ticks
  would change nothing, and the activity skips them (:class:`Wake`).
"""

from __future__ import annotations

import functools
import re
from collections.abc import Callable, Mapping, MutableMapping, Sequence
from dataclasses import dataclass, field
from datetime import datetime, timedelta
from enum import Enum
from pathlib import Path
from typing import TYPE_CHECKING, Any

import yaml

from activities.errors import BehaviorError
from activities.template import PROFILE_NAMESPACES, Missing, lookup, render
from dms.kernel.messages import ScreenChoice, Speech, Touch

if TYPE_CHECKING:
    from activities.context import ActivityContext

Event = Speech | ScreenChoice | Touch
PREEMPTED = "preempted"
"""The outcome of a state that was preempted; every state may end with it."""
MAX_STEPS_PER_TICK = 200
"""Instantaneous transitions allowed in one tick before the rest waits for the next."""


class Status(Enum):
    """What a state's ``update`` reports; the framework keeps it in ``Node.status``."""

    INVALID = "invalid"
    """Not entered yet, or stopped from outside (preempted, cancelled): not running."""
    RUNNING = "running"
    """Entered and not finished: tick it again."""
    DONE = "done"
    """Finished with an outcome (``Node.outcome``) for its container to follow."""
    FAILED = "failed"
    """Could not go on (a robot command failed or timed out): ``Node.error`` says why."""


_INVALID, _RUNNING, _DONE, _FAILED = Status.INVALID, Status.RUNNING, Status.DONE, Status.FAILED


@dataclass(slots=True)
class Wake:
    """What a waiting machine waits for: the first tick at or after ``deadline``, or the
    end of one of the robot ``commands`` it waits on.

    A state's ``update`` that is a pure function of the time against its deadlines and
    of whether its commands ended (and how) returns RUNNING again on every tick before
    then, so the ticks in between can be skipped without changing what happens
    (issue 14).
    """

    deadline: datetime | None = None
    commands: list[Any] = field(default_factory=list)
    """Command handles not finished yet: the machine wakes when one is (``finished``).
    A command that starts, or is queued again behind a more urgent one, changes nothing
    a waiting block reads."""

    def join(self, other: Wake) -> Wake:
        """Wait for both: the earlier deadline, every command (in place: each ``wake``
        makes its own)."""
        if other.deadline is not None and (self.deadline is None or other.deadline < self.deadline):
            self.deadline = other.deadline
        self.commands.extend(other.commands)
        return self

    def until(self, deadline: datetime | None) -> Wake:
        """Also wake at ``deadline`` (in place)."""
        return self.join(Wake(deadline))

    def holds(self, now: datetime) -> bool:
        """Whether a tick at ``now`` would still find nothing to do."""
        if self.deadline is not None and now >= self.deadline:
            return False
        for command in self.commands:  # a loop, not a generator: asked every tick
            if command.finished:
                break
        else:
            return True
        return False


class Runtime:
    """What the states of one running activity share: context, arguments, content."""

    def __init__(
        self,
        ctx: ActivityContext,
        args: Mapping[str, Any],
        content_dirs: Sequence[Path] = (),
    ) -> None:
        self.ctx = ctx
        self.args = dict(args)
        self.content_dirs = tuple(content_dirs)
        self.redirect: str | None = None
        self.on_enter: Callable[[Node], None] | None = None
        """Called when a state is entered (the stepper and tests listen)."""
        self.epoch = 0
        """Counts the changes of any state's status or of a machine's current state, and
        what reaches a state from outside (a preemption request, a pause or resume, an
        event taken): the active path is worked out again only when it moved, and a
        sleeping machine (:class:`Wake`) wakes (issue 14)."""

    def content(self, name: str) -> Any:
        return _load_content(self.content_dirs, name)

    def resolver(self, ud: Mapping[str, Any]) -> Callable[[str], Any]:
        """Look up ``path`` in the profiles, args, content files or userdata."""
        profiles: Mapping[str, Mapping[str, Any]] | None = None

        def resolve(path: str) -> Any:
            nonlocal profiles
            parts = path.split(".")
            head = parts[0]
            if head in PROFILE_NAMESPACES:
                if profiles is None:
                    profiles = self.ctx.params()
                return lookup(profiles.get(head, {}), parts[1:])
            if head == "args":
                return lookup(self.args, parts[1:])
            if head == "content" and len(parts) >= 2:
                try:
                    data = self.content(parts[1])
                except BehaviorError:
                    raise Missing(path) from None
                return lookup(data, parts[2:])
            return lookup(ud, parts)

        return resolve

    def render(self, value: Any, ud: Mapping[str, Any]) -> Any:
        return render(value, self.resolver(ud))


@functools.lru_cache(maxsize=64)
def _load_content(dirs: tuple[Path, ...], name: str) -> Any:
    for directory in dirs:
        path = directory / f"{name}.yaml"
        if path.is_file():
            try:
                return yaml.safe_load(path.read_text(encoding="utf-8"))
            except yaml.YAMLError as error:
                raise BehaviorError(f"{path}: not valid YAML: {error}") from None
    raise BehaviorError(f"content file {name}.yaml not found")


def clear_content_cache() -> None:
    """Forget the content files read so far (after they were edited)."""
    _load_content.cache_clear()


class UserdataView(MutableMapping[str, Any]):
    """A state's window on its container's userdata (SMACH's Remapper).

    With declared keys, reading a key not in ``input_keys`` (or writing one not in
    ``output_keys``) raises KeyError; without declarations the state sees everything.
    ``remapping`` renames the state's keys to the container's.
    """

    def __init__(
        self,
        target: MutableMapping[str, Any],
        input_keys: Sequence[str] = (),
        output_keys: Sequence[str] = (),
        remapping: Mapping[str, str] | None = None,
    ) -> None:
        self._target = target
        self._open = not input_keys and not output_keys
        self._inputs = frozenset(input_keys) | frozenset(output_keys)
        self._outputs = frozenset(output_keys)
        self._remap = dict(remapping or {})

    def _key(self, key: str) -> str:
        return self._remap.get(key, key)

    def __getitem__(self, key: str) -> Any:
        if not self._open and key not in self._inputs:
            raise KeyError(key)
        # ``_key`` written out: a read passes through every view up to the machine's
        return self._target[self._remap.get(key, key)]

    def __setitem__(self, key: str, value: Any) -> None:
        if not self._open and key not in self._outputs:
            raise KeyError(f"{key} is not an output key")
        self._target[self._key(key)] = value

    def __delitem__(self, key: str) -> None:
        del self._target[self._key(key)]

    def __iter__(self) -> Any:
        if self._open:
            inverse = {v: k for k, v in self._remap.items()}
            return iter([inverse.get(k, k) for k in self._target])
        return iter([k for k in self._inputs if self._key(k) in self._target])

    def __len__(self) -> int:
        return len(list(iter(self)))


@dataclass
class Io:
    """A state's declared userdata keys and their remapping."""

    input_keys: tuple[str, ...] = ()
    output_keys: tuple[str, ...] = ()
    remapping: dict[str, str] = field(default_factory=dict)


class Node:
    """One state. Subclasses implement the hooks; the framework owns ``tick``."""

    kind = "state"
    is_container = False
    """Containers pass a preemption request on; leaves end ``preempted``."""

    def __init__(self, name: str, outcomes: Sequence[str], rt: Runtime, io: Io | None = None):
        self.name = name
        self.outcomes = tuple(outcomes)
        self.rt = rt
        self.io = io or Io()
        self._status = _INVALID
        self.outcome: str | None = None
        self.error: str | None = None
        self.paused = False
        self.ud: MutableMapping[str, Any] = {}
        self._preempt_requested = False
        self.entered = 0
        self._path = ""
        self._path_epoch = -1

    @property
    def status(self) -> Status:
        """Where the state is in its run; every change is counted in ``rt.epoch``."""
        return self._status

    @status.setter
    def status(self, value: Status) -> None:
        self._status = value
        self.rt.epoch += 1

    # ------------------------------------------------------------ hooks

    def initialise(self, now: datetime) -> None:
        """When entered (also when re-entered by a transition): reset and start."""

    def update(self, now: datetime) -> Status:
        """One tick: never blocks; return RUNNING, or DONE after setting ``outcome``."""
        raise NotImplementedError

    def terminate(self, now: datetime, new_status: Status) -> None:
        """When left: ``INVALID`` means stopped from outside; withdraw what still runs."""

    def on_pause(self, now: datetime) -> None:
        """Freeze: withdraw robot commands, stop the clocks."""

    def on_resume(self, now: datetime) -> None:
        """Thaw: restart what was being said or shown, restart the clocks."""

    def on_event(self, event: Event) -> bool:
        """An event while running; True if this state took it."""
        return False

    def wake(self, now: datetime) -> Wake | None:
        """After a tick at ``now`` that left this state running: what it waits for
        (:class:`Wake`), or None if its next tick may do something whatever happens
        (the default: a state must say it can sleep). A container asks only its running
        states: one left to be entered (the tick ran out of steps) must be ticked."""
        return None

    def children(self) -> Sequence[Node]:
        return ()

    def active_children(self) -> Sequence[Node]:
        return ()

    # ------------------------------------------------------------ framework

    def bind(self, container_ud: MutableMapping[str, Any]) -> None:
        """Give the state its view of its container's userdata (before entering)."""
        self.ud = UserdataView(
            container_ud, self.io.input_keys, self.io.output_keys, self.io.remapping
        )

    def tick(self, now: datetime) -> Status:
        """Enter if needed, honour a preemption request, else update once.

        A request waits while the state is paused (it is served at the first tick
        after ``resume``). A leaf asked before its first tick ends ``preempted``
        without running; a container is entered and passes the request on, so that
        a cleanup transition of its first state still runs.
        """
        # Module constants, not ``Status.X``: an enum member lookup costs more than the
        # test, and this runs for every active state every tick.
        status = self._status
        if status is _DONE or status is _FAILED:
            return status
        if self.paused:
            return _RUNNING
        if status is _INVALID:
            if self._preempt_requested and not self.is_container:
                self._preempt_requested = False
                return self._end(now, _DONE, PREEMPTED, enter_terminate=False)
            self.status = _RUNNING
            self.outcome = None
            self.error = None
            self.paused = False
            self.entered += 1
            if self.rt.on_enter is not None:
                self.rt.on_enter(self)
            self.initialise(now)
        if self._preempt_requested:
            self._preempt_requested = False
            if self.is_container:
                self.forward_preempt()
            else:
                self.stop(now)
                return self._end(now, _DONE, PREEMPTED, enter_terminate=False)
        status = self.update(now)
        if status is _RUNNING:
            return _RUNNING
        if status is _DONE:
            if self.outcome is None:
                self.outcome = self.outcomes[0] if self.outcomes else "done"
            return self._end(now, _DONE, self.outcome)
        if status is _FAILED:
            return self._end(now, _FAILED, None)
        return _RUNNING

    def _end(
        self, now: datetime, status: Status, outcome: str | None, enter_terminate: bool = True
    ) -> Status:
        if enter_terminate:
            self.terminate(now, status)
        self.status = status
        self.outcome = outcome
        self.paused = False
        return status

    def fail(self, error: str) -> Status:
        """For ``update``: end FAILED with ``error``."""
        self.error = error
        return _FAILED

    def finish(self, outcome: str) -> Status:
        """For ``update``: end DONE with ``outcome``."""
        self.outcome = outcome
        return _DONE

    def stop(self, now: datetime) -> None:
        """Stop from outside, at every depth below: terminate(INVALID).

        A preemption request not serviced yet is dropped with the run it was meant
        for (SMACH and YASMIN clear it too): the next entry starts afresh.
        """
        if self._status is _RUNNING:
            for child in self.active_children():
                child.stop(now)
            self.terminate(now, _INVALID)
        self.status = _INVALID
        self.paused = False
        self._preempt_requested = False

    def forward_preempt(self) -> None:
        """Containers: pass a preemption request on to the states that run (or start)."""

    def reset(self) -> None:
        """Forget a finished run so the state can be entered again."""
        self.status = _INVALID
        self.outcome = None
        self.error = None

    def preempt(self) -> None:
        """Ask the state to end with ``preempted`` at its next tick (cooperative).

        Asking again before that tick is the same request; asking a finished state
        does nothing.
        """
        if self._status is not _DONE and self._status is not _FAILED:
            self._preempt_requested = True
            self.rt.epoch += 1

    @property
    def preempt_requested(self) -> bool:
        return self._preempt_requested

    def pause(self, now: datetime) -> None:
        if self._status is _RUNNING and not self.paused:
            for child in self.active_children():
                child.pause(now)
            self.paused = True
            self.rt.epoch += 1
            self.on_pause(now)

    def resume(self, now: datetime) -> None:
        """Thaw this state and those below; a leaf with a preemption request waiting
        does not restart its commands (its next tick ends it ``preempted``)."""
        if self._status is _RUNNING and self.paused:
            self.paused = False
            self.rt.epoch += 1
            if self.is_container or not self._preempt_requested:
                self.on_resume(now)
            for child in self.active_children():
                child.resume(now)

    def preempt_active(self) -> None:
        """Put a preemption request on this state and every active state below it now
        (the structure of a paused machine is frozen, so its leaves are known)."""
        self.preempt()
        for child in self.active_children():
            child.preempt_active()

    def deliver(self, event: Event) -> bool:
        """Offer ``event`` to this state and the states active below it."""
        if self._status is not _RUNNING or self.paused:
            return False
        if self.on_event(event):
            self.rt.epoch += 1
            return True
        return any(child.deliver(event) for child in self.active_children())

    def active_path(self) -> str:
        """The running states below this one (``A/B,C``); kept until a status changes,
        since the managers and the controller ask for it several times a tick."""
        epoch = self.rt.epoch
        if self._path_epoch == epoch:
            return self._path
        parts = []
        for child in self.active_children():
            if child._status is _RUNNING:
                below = child.active_path()
                parts.append(f"{child.name}/{below}" if below else child.name)
        path = ",".join(parts)
        self._path, self._path_epoch = path, epoch
        return path

    def describe(self) -> dict[str, Any]:
        """This state's part of ``Activity.structure()``."""
        out: dict[str, Any] = {
            "name": self.name,
            "kind": self.kind,
            "outcomes": list(self.outcomes),
            "status": self.status.value,
            "active": self._status is _RUNNING,
        }
        if self.paused:
            out["paused"] = True
        kids = self.children()
        if kids:
            out["states"] = [child.describe() for child in kids]
        return out


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
        if new_status is _DONE and not self.shares_userdata:
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
        if self._preempt_requested or current is None or current._status is not _RUNNING:
            return None
        return current.wake(now)

    def update(self, now: datetime) -> Status:
        steps = MAX_STEPS_PER_TICK
        while steps:  # (not a ``range``: most ticks end at the first state, still running)
            steps -= 1
            state = self.current
            if state is None:
                return self.fail("no active state")
            status = state.tick(now)
            if status is _RUNNING:
                return _RUNNING
            if status is _FAILED:
                return self.fail(f"{state.name}: {state.error}")
            outcome = state.outcome or ""
            target = self.transitions.get(state.name, {}).get(outcome)
            if target is None:
                target = outcome  # an outcome of the container passes through
                if outcome == PREEMPTED:
                    state.status = _INVALID  # not serviced here: it climbs
            self.transitions_taken += 1
            if target in self.states:
                self._enter(self.states[target])
                continue
            self.current = None
            self.rt.epoch += 1
            return self.finish(target)
        return _RUNNING

    def terminate(self, now: datetime, new_status: Status) -> None:
        super().terminate(now, new_status)
        if new_status is not _INVALID:
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
        return [s for s in self.states.values() if s._status is _RUNNING]

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
            if state._status is _DONE:
                continue
            wake = state.wake(now) if state._status is _RUNNING else None
            if wake is None:
                return None
            waiting.join(wake)
        return waiting

    def _wind_down(self) -> None:
        self._winding_down = True
        for state in self.states.values():
            if state._status is _INVALID or state._status is _RUNNING:
                state.preempt()

    def _tick_all(self, now: datetime) -> Node | None:
        for state in self.states.values():
            live = state._status is _INVALID or state._status is _RUNNING
            if live and state.tick(now) is _FAILED:
                return state
        return None

    def _match(self) -> str | None:
        for outcome, wanted in self.outcome_map.items():
            if all(
                self.states[child]._status is _DONE and self.states[child].outcome == out
                for child, out in wanted.items()
            ):
                return outcome
        return None

    def update(self, now: datetime) -> Status:
        """Tick every state; when the wait mode says so, preempt the others (their
        cleanup runs), and once all have ended read the outcome map in order."""
        failed = self._tick_all(now)
        if failed is None and not self._winding_down:
            done = [s for s in self.states.values() if s._status is _DONE]
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
        if any(state._status is not _DONE for state in self.states.values()):
            return _RUNNING
        outcome = self._match()
        if outcome is not None:
            return self.finish(outcome)
        if self._preempted:
            for state in self.states.values():
                state.status = _INVALID  # not serviced here: it climbs
            return self.finish(PREEMPTED)
        return self.finish(self.default_outcome)

    def _stop_all(self, now: datetime) -> None:
        for state in self.states.values():
            if state._status is _RUNNING:
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
        return [self.state] if self.state._status is _RUNNING else []

    def forward_preempt(self) -> None:
        if self.index < len(self.items):
            self.state.preempt()

    def wake(self, now: datetime) -> Wake | None:
        if self._preempt_requested or self.state._status is not _RUNNING:
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
            if status is _RUNNING:
                return _RUNNING
            if status is _FAILED:
                return self.fail(f"{self.state.name}: {self.state.error}")
            outcome = self.state.outcome or ""
            if outcome in self.break_on:
                return self.finish(self.break_on[outcome])
            if outcome not in self.continue_on:
                if outcome == PREEMPTED:
                    self.state.status = _INVALID  # not serviced here: it climbs
                return self.finish(outcome)
            self.index += 1
            self._next()
        return _RUNNING

    def active_path(self) -> str:
        below = super().active_path()
        return below

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
        return [self.state] if self.state._status is _RUNNING else []

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
        if self.state._status is not _RUNNING:
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
        if status is _FAILED:
            return self.fail(f"{self.state.name}: {self.state.error}")
        if status is _DONE:
            if self.state.outcome == PREEMPTED:
                self.state.status = _INVALID  # a guard never services it: it climbs
            return self.finish(self.state.outcome or "")
        return _RUNNING

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
