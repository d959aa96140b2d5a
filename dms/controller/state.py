"""What one tick leaves behind: :class:`TickRecord`, logged, published and asserted.

The daemon publishes a record's ``decisions`` on ``dms/decision`` and its ``state`` on
``dms/state``; simulations hand it to their listeners; tests assert on it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from datetime import datetime
from typing import Literal

from dms.controller.drives import motivation_snapshot
from dms.kernel.clock import iso
from dms.kernel.messages import (
    ActivityState,
    Channel,
    Decision,
    DmsState,
    Mode,
    MotivationSnapshot,
    UserState,
)
from motivation import MotivationModel, MotivationState


@dataclass(frozen=True, slots=True)
class ActivityFacts:
    """The current or suspended activity as a tick leaves it (``ActivityState``'s fields)."""

    name: str
    manager: str
    status: Literal["running", "paused"]
    state: str
    """The active states below the root, e.g. ``GAME/ROUNDS/ROUND/ASK``."""

    def message(self) -> ActivityState:
        return ActivityState(
            name=self.name, manager=self.manager, status=self.status, state=self.state
        )


@dataclass(frozen=True, slots=True)
class UserFacts:
    """The session's user as a tick leaves them (``UserState``'s fields)."""

    id: str
    ready: bool
    proactivity: str
    p_user: float

    def message(self) -> UserState:
        return UserState(
            id=self.id, ready=self.ready, proactivity=self.proactivity, p_user=self.p_user
        )


@dataclass(frozen=True, slots=True)
class TickRecord:
    """What one tick decided and the state it left, taken at the end of the tick."""

    tick: int
    time: datetime
    urgent: bool
    decisions: tuple[Decision, ...]
    robot: str
    mode: Mode
    user: UserFacts | None
    current: ActivityFacts | None
    """The current activity (running or paused), if any."""
    suspended: ActivityFacts | None
    """The activity a reminder paused, if any."""
    inputs: Mapping[str, Literal["ok", "stale", "missing", "not_published"]]
    robot_link: Literal["ok", "offline"]
    failing_channel: Channel | None
    """The output channel whose commands keep failing, if any."""
    motivation_state: MotivationState | None
    """The motivation model's own state after the tick (None before the first step)."""
    model: MotivationModel = field(repr=False)

    @property
    def activity(self) -> str | None:
        """The current activity's name, if any."""
        return self.current.name if self.current is not None else None

    # The record holds plain values; the messages (``motivation``, ``state``) are made
    # each time they are read, not at every tick: a simulation reads neither, and
    # validating them at every tick would cost half again of the 30-day simulation's
    # time (measured: 29.3 s against 19.2 s of CPU for
    # ``dms sim longterm --days 30 --users 3``).

    @property
    def motivation(self) -> MotivationSnapshot:
        """``state.motivation`` alone."""
        return motivation_snapshot(self.model, self.motivation_state)

    @property
    def state(self) -> DmsState:
        """The message on ``dms/state``."""
        return DmsState(
            robot=self.robot,
            tick=self.tick,
            time=iso(self.time),
            mode=self.mode,
            user=self.user.message() if self.user is not None else None,
            activity=self.current.message() if self.current is not None else None,
            suspended=self.suspended.message() if self.suspended is not None else None,
            motivation=self.motivation,
            inputs=self.inputs,
            robot_link=self.robot_link,
            failing_channel=self.failing_channel,
        )
