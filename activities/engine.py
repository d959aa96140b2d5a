"""The tick-based state-machine engine: a state, its status, its userdata, its sleep.

A :class:`Node` is a state with outcomes. The framework owns :meth:`Node.tick`; a
state implements the py_trees-style hooks ``initialise`` (entered), ``update`` (one
tick, never blocks, returns a :class:`Status`) and ``terminate`` (left, with the new
status: ``INVALID`` means it was stopped from outside). On top come SMACH's semantics
(the containers are in :mod:`activities.containers`):

- userdata: each container holds a dict; a state sees it through a
  :class:`UserdataView` limited to its declared ``input_keys``/``output_keys`` and
  renamed by ``remapping``;
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
from collections.abc import Callable, Mapping, MutableMapping, Sequence
from dataclasses import dataclass, field
from datetime import datetime
from enum import Enum
from pathlib import Path
from typing import TYPE_CHECKING, Any

import yaml

from activities.errors import BehaviorError
from activities.template import PROFILE_NAMESPACES, Missing, lookup, render
from dms.kernel.messages import ScreenChoice, Speech, Touch
from dms.kernel.yamlfile import load_plain

if TYPE_CHECKING:
    from activities.context import ActivityContext
    from activities.task_frames import TaskFrames

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


@dataclass(slots=True)
class Wake:
    """What a waiting machine waits for: the first tick at or after ``deadline``, or the
    end of one of the robot ``commands`` it waits on.

    A state's ``update`` that is a pure function of the time against its deadlines and
    of whether its commands ended (and how) returns RUNNING again on every tick before
    then, so the ticks in between can be skipped without changing what happens.
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
        return not any(command.finished for command in self.commands)


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
        self.task_frames: TaskFrames | None = None
        """The behavior's task frames (``frames:``), with their last known places."""
        self.epoch = 0
        """Counts the changes of any state's status or of a machine's current state, and
        what reaches a state from outside (a preemption request, a pause or resume, an
        event taken): when it moves, a sleeping machine (:class:`Wake`) wakes."""

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
    return read_content(dirs, name)


def read_content(dirs: tuple[Path, ...], name: str) -> Any:
    """Content file ``name`` from the first of ``dirs`` that has it, read now (a run
    reads through a cache; the loader's checks read the files as they are)."""
    for directory in dirs:
        path = directory / f"{name}.yaml"
        if path.is_file():
            try:
                return load_plain(path.read_text(encoding="utf-8"))  # aliases bounded
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
        return self._target[self._key(key)]

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
        self._status = Status.INVALID
        self.outcome: str | None = None
        self.error: str | None = None
        self.paused = False
        self.ud: MutableMapping[str, Any] = {}
        self._bound_to: MutableMapping[str, Any] | None = None
        """The container userdata ``ud`` is a view of (see ``bind``)."""
        self._preempt_requested = False
        self.entered = 0

    @property
    def status(self) -> Status:
        """Where the state is in its run; every change is counted in ``rt.epoch``."""
        return self._status

    @status.setter
    def status(self, value: Status) -> None:
        # A state's own moves (entered, ended, reset) write ``_status`` and count the
        # change themselves: through this setter, a call from C into Python, they made
        # a transition of bench/bench_behaviors.py's flat loop 11 % longer (19.9 k
        # instructions against 17.9 k).
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
        """Give the state its view of its container's userdata (before entering).

        A machine binds a state at each transition into it; while the container's
        userdata is the same mapping, the view made the first time is kept (its keys
        are declared when the machine is built).
        """
        if self._bound_to is not container_ud:
            self.ud = UserdataView(
                container_ud, self.io.input_keys, self.io.output_keys, self.io.remapping
            )
            self._bound_to = container_ud

    def tick(self, now: datetime) -> Status:
        """Enter if needed, honour a preemption request, else update once.

        A request waits while the state is paused (it is served at the first tick
        after ``resume``). A leaf asked before its first tick ends ``preempted``
        without running; a container is entered and passes the request on, so that
        a cleanup transition of its first state still runs.
        """
        # The running case first, each member read once: on Python 3.11 a read of
        # ``Status.X`` costs about 70 ns, a local name 7 ns (the enum's metaclass defines
        # ``__getattr__``, which takes every read of a class attribute off the fast path).
        status = self._status
        if status is Status.RUNNING:
            if self.paused:
                return status
        elif status is Status.INVALID:
            if self.paused:
                return Status.RUNNING
            if self._preempt_requested and not self.is_container:
                self._preempt_requested = False
                return self._end(now, Status.DONE, PREEMPTED, enter_terminate=False)
            self._status = Status.RUNNING
            self.rt.epoch += 1
            self.outcome = None
            self.error = None
            self.entered += 1
            if self.rt.on_enter is not None:
                self.rt.on_enter(self)
            self.initialise(now)
        else:
            return status  # DONE or FAILED: ended, until a reset
        if self._preempt_requested:
            self._preempt_requested = False
            if self.is_container:
                self.forward_preempt()
            else:
                self.stop(now)
                return self._end(now, Status.DONE, PREEMPTED, enter_terminate=False)
        status = self.update(now)
        if status is Status.RUNNING:
            return status
        if status is Status.DONE:
            if self.outcome is None:
                self.outcome = self.outcomes[0] if self.outcomes else "done"
            return self._end(now, status, self.outcome)
        if status is Status.FAILED:
            return self._end(now, status, None)
        return Status.RUNNING

    def _end(
        self, now: datetime, status: Status, outcome: str | None, enter_terminate: bool = True
    ) -> Status:
        if enter_terminate:
            self.terminate(now, status)
        self._status = status
        self.rt.epoch += 1
        self.outcome = outcome
        self.paused = False
        return status

    def fail(self, error: str) -> Status:
        """For ``update``: end FAILED with ``error``."""
        self.error = error
        return Status.FAILED

    def finish(self, outcome: str) -> Status:
        """For ``update``: end DONE with ``outcome``."""
        self.outcome = outcome
        return Status.DONE

    def stop(self, now: datetime) -> None:
        """Stop from outside, at every depth below: terminate(INVALID).

        A preemption request not serviced yet is dropped with the run it was meant
        for (SMACH and YASMIN clear it too): the next entry starts afresh.
        """
        if self.status is Status.RUNNING:
            for child in self.active_children():
                child.stop(now)
            self.terminate(now, Status.INVALID)
        self.status = Status.INVALID
        self.paused = False
        self._preempt_requested = False

    def forward_preempt(self) -> None:
        """Containers: pass a preemption request on to the states that run (or start)."""

    def reset(self) -> None:
        """Forget a finished run so the state can be entered again."""
        self._status = Status.INVALID
        self.rt.epoch += 1
        self.outcome = None
        self.error = None

    def preempt(self) -> None:
        """Ask the state to end with ``preempted`` at its next tick (cooperative).

        Asking again before that tick is the same request; asking a finished state
        does nothing.
        """
        if self.status is not Status.DONE and self.status is not Status.FAILED:
            self._preempt_requested = True
            self.rt.epoch += 1

    @property
    def preempt_requested(self) -> bool:
        return self._preempt_requested

    def pause(self, now: datetime) -> None:
        if self.status is Status.RUNNING and not self.paused:
            for child in self.active_children():
                child.pause(now)
            self.paused = True
            self.rt.epoch += 1
            self.on_pause(now)

    def resume(self, now: datetime) -> None:
        """Thaw this state and those below; a leaf with a preemption request waiting
        does not restart its commands (its next tick ends it ``preempted``)."""
        if self.status is Status.RUNNING and self.paused:
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
        if self.status is not Status.RUNNING or self.paused:
            return False
        if self.on_event(event):
            self.rt.epoch += 1
            return True
        return any(child.deliver(event) for child in self.active_children())

    def active_path(self) -> str:
        """The running states below this one (``A/B,C``)."""
        parts = []
        for child in self.active_children():
            if child.status is Status.RUNNING:
                below = child.active_path()
                parts.append(f"{child.name}/{below}" if below else child.name)
        return ",".join(parts)

    def describe(self) -> dict[str, Any]:
        """This state's part of ``Activity.structure()``."""
        out: dict[str, Any] = {
            "name": self.name,
            "kind": self.kind,
            "outcomes": list(self.outcomes),
            "status": self.status.value,
            "active": self.status is Status.RUNNING,
        }
        if self.paused:
            out["paused"] = True
        kids = self.children()
        if kids:
            out["states"] = [child.describe() for child in kids]
        return out
