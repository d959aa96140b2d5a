"""The simulated Mini's body: five motors that move toward their targets over time.

Each joint turns toward its target at its top speed (``dms.kernel.body.JOINTS``) and
stops at its limits; :meth:`SimBody.advance` moves the clock on, :meth:`SimBody.aim`
sets targets (a gaze, a pointing arm, a gesture's pose). The joint state is what the
robot reports on ``robot/joints``, so that tests and the viewer see where it looks.
Pure: it takes ``now`` and keeps no thread.
"""

from __future__ import annotations

from collections.abc import Mapping
from datetime import datetime

from dms.kernel.body import JOINTS, NEUTRAL


class SimBody:
    """Joint positions and targets on a virtual clock."""

    def __init__(self, now: datetime, positions: Mapping[str, float] | None = None) -> None:
        self.positions: dict[str, float] = {**NEUTRAL, **(positions or {})}
        self.targets: dict[str, float] = dict(self.positions)
        self._at = now

    def aim(self, targets: Mapping[str, float], now: datetime) -> None:
        """Move the named joints toward ``targets`` (clamped to their limits) from now.

        Raises:
            KeyError: a joint the Mini does not have.
        """
        self.advance(now)
        for name, angle in targets.items():
            self.targets[name] = JOINTS[name].clamp(float(angle))

    def advance(self, now: datetime) -> dict[str, float]:
        """The joint positions at ``now``: each moved toward its target at its speed."""
        elapsed = (now - self._at).total_seconds()
        if elapsed > 0.0:  # a time before the last is not a move back
            self._at = now
            if self.targets != self.positions:
                for name, target in self.targets.items():
                    position = self.positions[name]
                    step = JOINTS[name].speed * elapsed
                    if abs(target - position) <= step:
                        self.positions[name] = target
                    else:
                        self.positions[name] = position + (step if target > position else -step)
        return dict(self.positions)

    @property
    def moving(self) -> bool:
        return any(abs(self.targets[n] - self.positions[n]) > 1e-9 for n in self.positions)
