"""Step 1 of the decision loop, the motivation's half: the drives, stepped every tick.

The motivation model is pure; :class:`Drives` keeps its state between ticks, feeds it
what the robot perceives, and answers the questions the choice asks of it: which
behavior the dominant motivation wants, which drive dominates, and when that will change.
"""

from __future__ import annotations

from collections.abc import Sequence
from datetime import datetime

import numpy as np

from dms.inputs import InputSnapshot
from dms.kernel import keys
from dms.kernel.messages import MotivationSnapshot, MotivationWhy, UserPerception
from motivation import (
    MotivationModel,
    MotivationState,
    Percepts,
    Stimuli,
    simulate,
)


class Drives:
    """The motivation model's state, stepped once a tick from the percepts."""

    def __init__(self, model: MotivationModel) -> None:
        self.model = model
        self.state: MotivationState | None = None
        """None until the first tick."""
        self._last_step: float | None = None
        """Monotonic seconds of the last step: a wall clock set back or forward would
        freeze the drives or age them by the size of the step."""
        self._percepts: Percepts | None = None
        self._stimuli: Stimuli | None = None

    def step(
        self,
        snapshot: InputSnapshot,
        user: UserPerception | None,
        touches: Sequence[tuple[str, str]],
        running: str | None,
        now: datetime,
        monotonic: float,
    ) -> None:
        """Step the drives to ``now`` under what is perceived (missing inputs: None,
        not considered) while ``running`` runs (None: nothing, or it is paused).

        The step's length is measured on the monotonic clock; the wall clock's ``now``
        only says the hour, for the daily rhythm.
        """
        model = self.model
        if self.state is None:
            self.state = model.initial_state(now)
        if self._last_step is None:
            self._last_step = monotonic
        dt = monotonic - self._last_step
        if dt <= 0:
            return
        values = snapshot.values
        percepts = Percepts(
            (user.present if user else False) if keys.PERCEPTION_USER in values else None,
            user.engagement if user else None,
            snapshot.env_params if keys.PARAMS_ENV in values else None,
            tuple(touches),
        )
        # The same percepts give the same stimuli, and the room rarely changes between
        # ticks: working them out again every tick would cost half again of the 30-day
        # simulation's time (measured: 29.9 s against 19.2 s of CPU).
        if percepts != self._percepts or self._stimuli is None:
            self._stimuli = model.stimuli(percepts)
            self._percepts = percepts
        self.state = model.step(self.state, dt, self._stimuli, running, now)
        self._last_step = monotonic

    def behavior(self) -> str:
        """The behavior of the dominant motivation (``wait`` before the first step)."""
        if self.state is None:
            return "wait"
        return self.model.behavior(self.state)

    def dominant(self) -> str | None:
        if self.state is None:
            return None
        return self.model.dominant(self.state)

    def snapshot(self) -> MotivationSnapshot:
        """DmsState's ``motivation`` (before the first step: no drives, wellbeing 100)."""
        return motivation_snapshot(self.model, self.state)

    def why(self) -> MotivationWhy | None:
        """The drives behind a decision, for its ``why``."""
        if self.state is None:
            return None
        snapshot = self.snapshot()
        return MotivationWhy(dominant=snapshot.dominant, drives=snapshot.drives)

    def next_change(
        self, now: datetime, horizon_s: float, running: str | None, tick_s: float
    ) -> float | None:
        """Seconds from ``now`` to the tick at which, with the percepts as they are, the
        motivated behavior would change; None if not within ``horizon_s``.

        For simulations that skip the ticks of an empty room: they may jump this far and
        lose nothing, since the motivation is exact over any step.
        """
        state, percepts = self.state, self._percepts
        if state is None or percepts is None:
            return None
        model = self.model
        stimuli = model.stimuli(Percepts(percepts.user_present, percepts.engagement, percepts.env))
        run = simulate(model, state, now, horizon_s, stimuli, running=running, tick_s=tick_s)
        expected = model.behavior(state)
        behaviors = [*model.table.behaviors, model.config.idle_behavior]
        # the dominant drive's index at each tick, -1 for none: the idle behavior, last
        same = np.array([behavior == expected for behavior in behaviors])[run.dominant]
        if same.all():
            return None
        return (int(np.argmin(same)) + 1) * tick_s  # the first tick of another behavior


def motivation_snapshot(
    model: MotivationModel, state: MotivationState | None
) -> MotivationSnapshot:
    """DmsState's ``motivation`` for ``state`` (None: before the first step)."""
    if state is None:
        return MotivationSnapshot(dominant=None, drives={}, motivations={}, wellbeing=100.0)
    return MotivationSnapshot(**model.snapshot(state))
