"""The leaf state every block is: parameters bound on entry, robot commands, waiting.

A block's ``begin`` sends its commands through the expression arbiter with the
activity's source; by default it is done when they all ended, and a command that
failed or was never acknowledged fails the block (and the activity) with the reason.
"""

from __future__ import annotations

from collections.abc import Mapping
from datetime import datetime, timedelta
from typing import Any, ClassVar, Generic, TypeVar, cast

from pydantic import ValidationError

from activities.blocks.params import BINDING, BlockParams, explain, fields_of, holds_placeholder
from activities.engine import Io, Node, Runtime, Status, Wake
from activities.errors import BehaviorError
from activities.template import render
from dms.kernel.expression import CommandHandle, CommandStatus, Priority
from dms.kernel.messages import Channel

_BROKEN = frozenset({CommandStatus.FAILED, CommandStatus.TIMED_OUT})
"""What a command ends with when the robot could not do it: the block fails."""

P = TypeVar("P", bound=BlockParams)


class Block(Node, Generic[P]):
    """A leaf state: binds its parameters on entry, sends robot commands, waits on them.

    ``PARAMS`` is the model of the parameters a file writes; ``self.args`` holds this
    entry's values, an instance of ``P`` (the same model, but for ``menu``, which asks
    an ``ask`` question made of its own parameters).
    """

    kind = "block"
    NAME: ClassVar[str] = "block"
    """The block's name in behavior files, its key in :data:`activities.blocks.BLOCKS`."""
    PARAMS: ClassVar[type[BlockParams]] = BlockParams
    OUTCOMES: ClassVar[tuple[str, ...]] = ("done",)
    DOC: ClassVar[str] = ""

    args: P
    """The parameters of this entry, bound and validated (set by :meth:`bind_params`)."""

    def __init__(self, name: str, rt: Runtime, params: Mapping[str, Any], io: Io | None = None):
        super().__init__(name, self.outcomes_for(params), rt, io)
        self.params = dict(params)
        self.handles: list[CommandHandle] = []
        self._templated = {k: v for k, v in self.params.items() if holds_placeholder(v)}
        """The values to bind at each entry; the others are the same every time."""
        self._fixed: BlockParams | None = None

    @classmethod
    def outcomes_for(cls, params: Mapping[str, Any]) -> tuple[str, ...]:
        """The outcomes of a state of this block with ``params`` as written (most
        blocks: fixed). Called at load, before placeholders are bound."""
        return cls.OUTCOMES

    def describe(self) -> dict[str, Any]:
        out = super().describe()
        out["kind"] = self.NAME
        out["params"] = self.params
        return out

    # ------------------------------------------------------------ helpers

    def bound(self) -> BlockParams:
        """The parameters of this entry as a ``PARAMS`` instance.

        Without placeholders: validated once (the loader checked them) and reused.
        With: bound in the current userdata and profiles, then validated in lax mode
        (``"3"`` is 3) with :data:`Text` values read as text; a value that does not
        fit raises :class:`BehaviorError`, which fails the activity.
        """
        model = self.PARAMS
        if not self._templated:
            if self._fixed is None:
                self._fixed = model.model_validate(self.params)
            return self._fixed
        fields = fields_of(model)
        resolve = self.rt.resolver(self.ud)
        values = dict(self.params)
        for key, raw in self._templated.items():
            value = render(raw, resolve)
            if value is None or (value == "" and key not in fields.text):
                if key in fields.required:
                    values[key] = None
                else:
                    del values[key]  # bound to nothing: the default
            else:
                values[key] = value
        try:
            return model.model_validate(values, context=BINDING)
        except ValidationError as error:
            where, message = explain(model, error, values)[0]
            raw = self._templated.get(where or "")
            source = f" (bound from {raw!r})" if raw is not None else ""
            raise BehaviorError(f"{self.NAME}: {message}{source}") from None

    def bind_params(self) -> None:
        """Set ``self.args`` for this entry (called by :meth:`initialise`)."""
        self.args = cast(P, self.bound())

    def command(
        self,
        channel: Channel,
        action: str,
        args: Mapping[str, Any],
        now: datetime,
        priority: Priority = Priority.NORMAL,
    ) -> CommandHandle:
        handle = self.rt.ctx.expression.request(
            self.rt.ctx.source, channel, action, args, now, priority=priority
        )
        self.handles.append(handle)
        return handle

    def withdraw(self, now: datetime) -> None:
        """Interrupt this block's commands that still run."""
        for handle in self.handles:
            if not handle.finished:
                self.rt.ctx.expression.interrupt(handle, now)
        self.handles = []

    def command_error(self) -> str | None:
        for handle in self.handles:
            if handle.status in _BROKEN:
                reason = handle.detail or handle.status.value
                return f"{handle.channel} {handle.action} {handle.status.value}: {reason}"
        return None

    def commands_done(self) -> bool:
        return all(handle.finished for handle in self.handles)

    def initialise(self, now: datetime) -> None:
        self.handles = []
        self.bind_params()
        self.begin(now)

    def begin(self, now: datetime) -> None:
        """Start the block's work (also on resume, to restart it)."""

    def terminate(self, now: datetime, new_status: Status) -> None:
        if new_status is Status.INVALID:
            self.withdraw(now)

    def on_pause(self, now: datetime) -> None:
        self.withdraw(now)

    def on_resume(self, now: datetime) -> None:
        self.begin(now)

    def update(self, now: datetime) -> Status:
        error = self.command_error()
        if error is not None:
            return self.fail(error)
        if self.commands_done():
            return self.finish(self.OUTCOMES[0])
        return Status.RUNNING

    def wake(self, now: datetime) -> Wake | None:
        """This ``update`` reads only its commands' statuses: it waits for one to end."""
        return self.waiting_on_commands() if self.updates_as(Block) else None

    def updates_as(self, owner: type[Block[Any]]) -> bool:
        """Whether this block's ``update`` is ``owner``'s, the one whose ``wake`` is being
        asked, and reads the commands as Block does: a subclass that changes either may
        read something else, and ticks every tick unless its own ``wake`` says otherwise."""
        kind = type(self)
        return (
            kind.update is owner.update
            and kind.command_error is Block.command_error
            and kind.commands_done is Block.commands_done
        )

    def waiting_on_commands(self) -> Wake | None:
        """Sleep until a command ends (unless a preemption waits): whether they ended,
        and how, is all that :meth:`update` reads of them."""
        if self._preempt_requested:
            return None
        return Wake(None, [handle for handle in self.handles if not handle.finished])


class Countdown:
    """A deadline that survives a pause: the time left is kept while paused and runs
    on after it. Without seconds it never ends (the state waits to be cancelled)."""

    def __init__(self, now: datetime, seconds: float | None) -> None:
        self.deadline = now + timedelta(seconds=seconds) if seconds is not None else None
        self.remaining: float | None = None

    def pause(self, now: datetime) -> None:
        if self.deadline is not None:
            self.remaining = max(0.0, (self.deadline - now).total_seconds())

    def resume(self, now: datetime) -> None:
        if self.remaining is not None:
            self.deadline = now + timedelta(seconds=self.remaining)
            self.remaining = None

    def over(self, now: datetime) -> bool:
        return self.deadline is not None and now >= self.deadline
