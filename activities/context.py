"""What an activity needs from the daemon: the expression arbiter, parameters, rules."""

from __future__ import annotations

import random
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any, Protocol

from dms.kernel.expression import ExpressionArbiter
from dms.kernel.frames import FrameStore


class RuleResult(Protocol):
    """What a rule component gives back: its activations, in order."""

    @property
    def activate(self) -> Sequence[str]: ...


class RuleEvaluator(Protocol):
    """Evaluates a DMSL component; ``None`` when the component is not defined."""

    def evaluate(
        self, component: str, params: Mapping[str, Mapping[str, Any]]
    ) -> RuleResult | None: ...


def _no_params() -> Mapping[str, Mapping[str, Any]]:
    return {"user": {}, "robot": {}, "env": {}}


def _ignore(_name: str, _value: Any) -> None:
    return None


def _same_time(now: datetime) -> datetime:
    return now


@dataclass
class ActivityContext:
    """The daemon's side of a running activity, given to ``BehaviorLibrary.create``."""

    expression: ExpressionArbiter
    source: str = "activity"
    """The expression source of this activity's commands, e.g. ``activity:quiz``."""
    params: Callable[[], Mapping[str, Mapping[str, Any]]] = _no_params
    """``{"user": {...}, "robot": {...}, "env": {...}}``, read when a block binds its parameters."""
    rules: RuleEvaluator | None = None
    rng: random.Random = field(default_factory=lambda: random.Random(0))
    set_user_param: Callable[[str, Any], None] = _ignore
    """Stores a value in the present user's profile (the ``set_param`` block)."""
    frames: FrameStore | None = None
    """Where things are (``user``, ``face:<id>``, ``object:<name>``, the body): what
    ``look_at``, ``point_at`` and ``attend`` aim at. None: the robot knows no frames."""
    joints: Mapping[str, float] = field(default_factory=dict)
    """The robot's joint state now (radians), kept current by the daemon."""
    steady: Callable[[datetime], datetime] = _same_time
    """The daemon's wall time ``now`` on its steady clock, which the wall clock's steps do
    not move (:class:`~dms.kernel.clock.SteadyTime`): an activity's waits, timers and
    cleanup limit, and the commands it sends, run on it. The identity by default."""
