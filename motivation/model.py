"""The motivational model: drives, motivations, the dominant one, wellbeing.

Pure: every method takes the state and ``now`` and returns a new state; nothing
reads the clock. The controller calls ``step`` once a tick; simulations and the
plot jump ahead with ``motivation.trajectory``'s ``advance`` and ``simulate``,
which give the same numbers as stepping at the tick rate.

- Drive ``D_i`` in [0, 100] grows at its daily-modulated rate and falls while a
  behavior that satisfies it runs or a stimulus relieves it.
- Motivation ``M_i = D_i + alpha_i * w_i`` when ``D_i >= L_i`` (for the dominant
  drive: while ``D_i`` stays at or above its satiation level), else 0.
- The dominant motivation changes only when another exceeds it by ``hysteresis`` or
  it lets go; wellbeing is ``100 - sum(omega_i * D_i) / sum(omega_i)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from datetime import UTC, datetime, tzinfo

import numpy as np

from motivation.config import MotivationConfig
from motivation.dynamics import HIGH, LOW, OMEGA, FloatArray, evolve
from motivation.stimuli import Percepts, Stimuli, caress_count, source_levels

NO_DOMINANT = -1


@dataclass(frozen=True)
class MotivationState:
    """Drives, the stimulus levels they were last seen with, and the dominant drive's index."""

    drives: FloatArray
    levels: FloatArray
    dominant: int = NO_DOMINANT


@dataclass(frozen=True)
class DriveTable:
    """The configuration as arrays, one entry per enabled drive, per second."""

    names: tuple[str, ...]
    base: FloatArray
    swing: FloatArray
    peak_s: FloatArray
    threshold: FloatArray
    release: FloatArray
    alpha: FloatArray
    omega: FloatArray
    touch_relief: FloatArray
    behaviors: tuple[str, ...]

    @classmethod
    def of(cls, config: MotivationConfig) -> DriveTable:
        drives = config.active_drives

        def column(values: list[float]) -> FloatArray:
            return np.array(values, dtype=np.float64)

        return cls(
            names=tuple(drives),
            base=column([d.rate_per_hour / 3600.0 for d in drives.values()]),
            swing=column([d.rate_per_hour * d.amplitude / 3600.0 for d in drives.values()]),
            peak_s=column([d.peak_hour * 3600.0 for d in drives.values()]),
            threshold=column([d.threshold for d in drives.values()]),
            release=column([d.release for d in drives.values()]),
            alpha=column([d.stimulus_weight for d in drives.values()]),
            omega=column([d.wellbeing_weight for d in drives.values()]),
            touch_relief=column([d.touch_relief for d in drives.values()]),
            behaviors=tuple(d.behavior for d in drives.values()),
        )


def day_seconds(now: datetime, zone: tzinfo) -> float:
    """Seconds since local midnight at ``now``, the clock of the daily rhythm.

    Seconds since 1970 as a float resolve only 2.4e-7 s, so ``end - dt`` of a step
    rounds; at a drive moving a point a second that was 1e-6 points a step. Small
    numbers keep the closed form exact for any ``dt``.
    """
    local = now.astimezone(zone)
    return local.hour * 3600.0 + local.minute * 60.0 + local.second + local.microsecond / 1e6


@dataclass(frozen=True, slots=True)
class _StepPlan:
    """What ``step`` needs of its inputs, per drive: (instant relief, a, b, peak, sign,
    ``b / OMEGA``: the daily wave's factor in ``integral``)."""

    stimuli: Stimuli
    running: str | None
    rows: tuple[tuple[float, float, float, float, int, float], ...]


class MotivationModel:
    """The model for one configuration and time zone; holds no state of its own (one
    memo of the last step's inputs, which gives the same numbers)."""

    def __init__(self, config: MotivationConfig | None = None, zone: tzinfo = UTC) -> None:
        self.config = config or MotivationConfig()
        self.zone = zone
        self.table = DriveTable.of(self.config)
        drives = self.config.active_drives
        self.names = self.table.names
        self._satisfaction: dict[str | None, FloatArray] = {None: np.zeros(len(self.names))}
        for behavior in {name for d in drives.values() for name in d.satisfied_by}:
            self._satisfaction[behavior] = np.array(
                [d.satisfied_by.get(behavior, 0.0) / 60.0 for d in drives.values()],
                dtype=np.float64,
            )
        self._awake: dict[str | None, FloatArray] = {None: np.ones(len(self.names))}
        for behavior in {name for d in drives.values() for name in d.dormant_during}:
            self._awake[behavior] = np.array(
                [0.0 if behavior in d.dormant_during else 1.0 for d in drives.values()],
                dtype=np.float64,
            )
        self._relief_per_source = {
            name: {source: per_minute / 60.0 for source, per_minute in d.relieved_by.items()}
            for name, d in drives.items()
        }
        self._drive_sources = {name: d.stimuli for name, d in drives.items()}
        self._plan: _StepPlan | None = None
        """The last step's inputs worked out: the controller passes the same ``Stimuli``
        object tick after tick while the room does not change (a memo, not state)."""

    # ------------------------------------------------------------------ inputs

    def initial_state(self, now: datetime) -> MotivationState:
        """The configured initial drives, no stimulus; ``now`` only fixes the dominant."""
        del now  # the initial drives are the same at any hour
        drives = np.array([d.initial for d in self.config.active_drives.values()], dtype=np.float64)
        levels = np.zeros(len(self.names))
        return MotivationState(drives, levels, self.next_dominant(NO_DOMINANT, drives, levels))

    def stimuli(self, percepts: Percepts) -> Stimuli:
        """The stimuli per drive for what is perceived now."""
        sources = source_levels(percepts, self.config.stimuli)
        levels = [
            max((sources[s] for s in self._drive_sources[name]), default=0.0) for name in self.names
        ]
        relief = [
            sum(rate * sources[s] for s, rate in self._relief_per_source[name].items())
            for name in self.names
        ]
        return Stimuli(
            np.array(levels, dtype=np.float64),
            np.array(relief, dtype=np.float64),
            self.table.touch_relief * caress_count(percepts),
        )

    def no_stimuli(self) -> Stimuli:
        """Nothing perceived: an empty room at an unknown light level."""
        zeros = np.zeros(len(self.names))
        return Stimuli(zeros, zeros.copy(), zeros.copy())

    def satisfaction(self, running: str | None) -> FloatArray:
        """Points per second ``running`` takes off each drive."""
        return self._satisfaction.get(running, self._satisfaction[None])

    def net_growth(self, stimuli: Stimuli, running: str | None) -> FloatArray:
        """The constant part ``a`` of each drive's rate for these inputs."""
        awake = self._awake.get(running, self._awake[None])
        return np.asarray(
            self.table.base * awake - self.satisfaction(running) - stimuli.relief, dtype=np.float64
        )

    def swing(self, running: str | None) -> FloatArray:
        """The daily part ``b`` of each drive's rate while ``running`` runs."""
        return np.asarray(
            self.table.swing * self._awake.get(running, self._awake[None]), dtype=np.float64
        )

    # ------------------------------------------------------------------ the step

    def step(
        self,
        state: MotivationState,
        dt: float,
        stimuli: Stimuli,
        running: str | None,
        now: datetime,
    ) -> MotivationState:
        """The state at ``now`` from the state at ``now - dt`` under these inputs, exactly.

        The caresses of ``stimuli`` count once, at the start; the dominant motivation is
        chosen at ``now``. The daily rhythm is read off the wall clock at ``now``: a step
        across a daylight-saving change is taken wholly in the new offset (at the
        daemon's 0.5 s ticks, that is half a second of rhythm).
        """
        if dt < 0:
            raise ValueError(f"dt must not be negative, got {dt}")
        end = day_seconds(now, self.zone)
        start = end - dt
        # A shortcut, for the simulations' wall time: each drive's rates are worked out once
        # per inputs (``_plan_for``), and ``evolve`` is written out for a rate that keeps
        # its sign (most ticks). Calling ``net_growth``, ``swing`` and ``evolve`` every
        # tick made the 30-minute session 1.2 to 1.5 times as long (best of three 0.20 s
        # against 0.17 s, medians 0.28 s against 0.18 s, measured).
        plan = self._plan
        if plan is None or plan.stimuli is not stimuli or plan.running != running:
            plan = self._plan = self._plan_for(stimuli, running)
        evolved: list[float] = []
        drives = state.drives.tolist()
        span = end - start
        for drive, (instant, a, b, peak, sign, wave) in zip(drives, plan.rows, strict=True):
            if sign == 0:  # the rate may turn inside the step: split it there
                evolved.append(evolve(max(0.0, drive - instant), a, b, peak, start, end))
                continue
            # ``evolve`` without its calls: the rate keeps its sign, so one clipped piece;
            # the change is ``integral(a, b, peak, start, end)``, written out
            change = a * span + wave * (
                math.sin(OMEGA * (end - peak)) - math.sin(OMEGA * (start - peak))
            )
            if instant or not LOW < drive <= HIGH:  # a caress, a drive at 0, a made-up state
                change = max(change, 0.0) if sign > 0 else min(change, 0.0)
                evolved.append(min(HIGH, max(LOW, max(0.0, drive - instant) + change)))
                continue
            # Most drives, most ticks: in (0, 100], only a change of the rate's sign moves
            # it, and only towards the wall it may hit (the same floats as the line above).
            if sign > 0:
                if change > 0.0:
                    drive = drive + change
                    if drive > HIGH:
                        drive = HIGH
            elif change < 0.0:
                drive = drive + change
                if drive < LOW:
                    drive = LOW
            evolved.append(drive)
        drives = np.array(evolved, dtype=np.float64)
        dominant = self.next_dominant(state.dominant, drives, stimuli.levels)
        return MotivationState(drives, stimuli.levels, dominant)

    def _plan_for(self, stimuli: Stimuli, running: str | None) -> _StepPlan:
        """Each drive's constant rate ``a``, daily swing ``b`` and peak under these inputs,
        and the sign its rate keeps (0 if it may turn), as ``evolve`` computes them."""
        rates = zip(
            stimuli.instant.tolist(),
            self.net_growth(stimuli, running).tolist(),
            self.swing(running).tolist(),
            self.table.peak_s.tolist(),
            strict=True,
        )
        rows: list[tuple[float, float, float, float, int, float]] = []
        for instant, a, b, peak in rates:
            sign = 1 if a >= b else -1 if a <= -b else 0  # as ``signed`` decides it
            rows.append((instant, a, b, peak, sign, b / OMEGA))
        return _StepPlan(stimuli, running, tuple(rows))

    # ------------------------------------------------------------------ reading a state

    def motivations(
        self, drives: FloatArray, levels: FloatArray, dominant: int = NO_DOMINANT
    ) -> FloatArray:
        """``M_i``: the drive plus its stimulus when active, else 0; the dominant drive
        stays active down to its satiation level."""
        table = self.table
        rows = zip(
            drives.tolist(),
            levels.tolist(),
            table.threshold.tolist(),
            table.release.tolist(),
            table.alpha.tolist(),
            strict=True,
        )
        values = [
            drive + alpha * level if drive >= (release if i == dominant else threshold) else 0.0
            for i, (drive, level, threshold, release, alpha) in enumerate(rows)
        ]
        return np.array(values, dtype=np.float64)

    def next_dominant(self, previous: int, drives: FloatArray, levels: FloatArray) -> int:
        """The dominant drive after ``previous``, with hysteresis; NO_DOMINANT if none is active."""
        table = self.table
        current = drives.tolist()
        alphas, stimulus = table.alpha.tolist(), levels.tolist()
        values = [d + a * w for d, a, w in zip(current, alphas, stimulus, strict=True)]
        best, best_value = NO_DOMINANT, -math.inf
        for i, threshold in enumerate(table.threshold.tolist()):
            if i != previous and current[i] >= threshold and values[i] > best_value:
                best, best_value = i, values[i]
        if previous == NO_DOMINANT:
            return best
        if current[previous] < table.release[previous]:
            return best  # it lets go (release <= threshold): the strongest active drive takes over
        if best != NO_DOMINANT and best_value > values[previous] + self.config.hysteresis:
            return best
        return previous

    def dominant(self, state: MotivationState) -> str | None:
        """The name of the dominant drive, or None."""
        return None if state.dominant == NO_DOMINANT else self.names[state.dominant]

    def behavior(self, state: MotivationState) -> str:
        """What the robot should do on its own now."""
        if state.dominant == NO_DOMINANT:
            return self.config.idle_behavior
        return self.table.behaviors[state.dominant]

    def wellbeing(self, drives: FloatArray) -> float:
        """``100 - sum(omega_i * D_i) / sum(omega_i)`` (100 when no drive has a weight)."""
        return float(self.wellbeings(drives[np.newaxis])[0])

    def wellbeings(self, drives: FloatArray) -> FloatArray:
        """The wellbeing of each row of ``drives`` (one state's drives a row)."""
        omega = self.table.omega
        total = float(omega.sum())
        if total == 0:
            return np.full(len(drives), 100.0)
        weighted = np.zeros(len(drives))
        # drive by drive, in order: a row gives the same float alone or among many (a
        # matrix product may sum in another order)
        for i, weight in enumerate(omega.tolist()):
            weighted = weighted + weight * drives[:, i]
        # clipped: with every drive at 100 the rounding of the mean can leave -1e-14
        return np.clip(100.0 - weighted / total, 0.0, 100.0)

    def snapshot(self, state: MotivationState) -> dict[str, object]:
        """The ``motivation`` field of DmsState, rounded to three places."""
        drives = state.drives
        motivations = self.motivations(drives, state.levels, state.dominant)
        names = self.names
        return {
            "dominant": self.dominant(state),
            "drives": {name: round(v, 3) for name, v in zip(names, drives.tolist(), strict=True)},
            "motivations": {
                name: round(v, 3) for name, v in zip(names, motivations.tolist(), strict=True)
            },
            "wellbeing": round(self.wellbeing(drives), 3),
        }
