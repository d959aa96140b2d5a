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

sin = math.sin


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


def round3(value: float) -> float:
    """``round(value, 3)``, bit for bit, at a third of its cost (the state has seven a tick).

    ``round`` finds the integer nearest to ``value * 1000`` exactly (ties to even) and
    divides it by 1000, correctly rounded. The product in floats is off by half an ulp
    at most, so its nearest integer is the same unless it lies near a half: there (and
    for negative, huge or not-a-number values) ``round`` itself decides.
    """
    scaled = value * 1000.0
    if 0.0 < scaled < 1e15:
        whole = math.floor(scaled)
        if abs(scaled - whole - 0.5) >= 1e-6:
            return (whole + 1 if scaled - whole > 0.5 else whole) / 1000.0
    elif scaled == 0.0:
        return value  # a zero keeps its sign, as with ``round``
    return round(value, 3)


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
    levels: list[float]


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
        self._rate_rows = [
            (float(b), float(w), float(p))
            for b, w, p in zip(self.table.base, self.table.swing, self.table.peak_s, strict=True)
        ]
        self._level_rows = [
            (float(t), float(r), float(a))
            for t, r, a in zip(
                self.table.threshold, self.table.release, self.table.alpha, strict=True
            )
        ]
        self._awake_rows = {name: row.tolist() for name, row in self._awake.items()}
        self._satisfaction_rows = {name: row.tolist() for name, row in self._satisfaction.items()}
        self._relief_per_source = {
            name: {source: per_minute / 60.0 for source, per_minute in d.relieved_by.items()}
            for name, d in drives.items()
        }
        self._drive_sources = {name: d.stimuli for name, d in drives.items()}
        self._omega = self.table.omega.tolist()
        self._omega_total = float(sum(self._omega))
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
        # Plain floats: for three drives numpy's per-call overhead would dominate the tick.
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
            change = a * span + wave * (sin(OMEGA * (end - peak)) - sin(OMEGA * (start - peak)))
            if instant or not LOW < drive <= HIGH:  # a caress, a drive at 0, a made-up state
                change = max(change, 0.0) if sign > 0 else min(change, 0.0)
                evolved.append(min(HIGH, max(LOW, max(0.0, drive - instant) + change)))
                continue
            # Most drives, most ticks: in (0, 100], only a change of the rate's sign moves
            # it, and only towards the wall it may hit. The same floats as the line above,
            # without its five calls of ``min`` and ``max`` (a fifth of the step).
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
        dominant = self._next_dominant(state.dominant, evolved, plan.levels)
        return MotivationState(np.array(evolved, dtype=np.float64), stimuli.levels, dominant)

    def _plan_for(self, stimuli: Stimuli, running: str | None) -> _StepPlan:
        """Each drive's constant rate ``a``, daily swing ``b`` and peak under these inputs,
        and the sign its rate keeps (0 if it may turn), as ``evolve`` computes them."""
        awake = self._awake_rows.get(running, self._awake_rows[None])
        satisfied = self._satisfaction_rows.get(running, self._satisfaction_rows[None])
        relief = stimuli.relief.tolist()
        instant = stimuli.instant.tolist()
        rows: list[tuple[float, float, float, float, int, float]] = []
        for i, (base, swing, peak) in enumerate(self._rate_rows):
            a = base * awake[i] - satisfied[i] - relief[i]
            b = swing * awake[i]
            sign = 1 if a >= b else -1 if a <= -b else 0  # as ``signed`` decides it
            rows.append((instant[i], a, b, peak, sign, b / OMEGA))
        return _StepPlan(stimuli, running, tuple(rows), stimuli.levels.tolist())

    # ------------------------------------------------------------------ reading a state

    def motivations(
        self, drives: FloatArray, levels: FloatArray, dominant: int = NO_DOMINANT
    ) -> FloatArray:
        """``M_i``: the drive plus its stimulus when active, else 0."""
        values = self._motivations(drives.tolist(), levels.tolist(), dominant)
        return np.array(values, dtype=np.float64)

    def _motivations(self, drives: list[float], levels: list[float], dominant: int) -> list[float]:
        out = []
        for i, (threshold, release, alpha) in enumerate(self._level_rows):
            floor = release if i == dominant else threshold
            out.append(drives[i] + alpha * levels[i] if drives[i] >= floor else 0.0)
        return out

    def next_dominant(self, previous: int, drives: FloatArray, levels: FloatArray) -> int:
        """The dominant drive after ``previous``, with hysteresis; NO_DOMINANT if none is active."""
        return self._next_dominant(previous, drives.tolist(), levels.tolist())

    def _next_dominant(self, previous: int, drives: list[float], levels: list[float]) -> int:
        rows = self._level_rows
        best, best_value = NO_DOMINANT, -math.inf
        for i, (threshold, _release, alpha) in enumerate(rows):
            if i != previous and drives[i] >= threshold:
                value = drives[i] + alpha * levels[i]
                if value > best_value:
                    best, best_value = i, value
        if previous == NO_DOMINANT:
            return best
        _threshold, release, alpha = rows[previous]
        if drives[previous] < release:
            return best  # it lets go (release <= threshold): the strongest active drive takes over
        if best != NO_DOMINANT and best_value > drives[previous] + alpha * levels[previous] + (
            self.config.hysteresis
        ):
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
        return self._wellbeing(drives.tolist())

    def _wellbeing(self, drives: list[float]) -> float:
        if self._omega_total == 0:
            return 100.0
        weighted = float(sum(w * d for w, d in zip(self._omega, drives, strict=True)))
        # clipped: with every drive at 100 the rounding of the mean can leave -1e-14
        return min(100.0, max(0.0, 100.0 - weighted / self._omega_total))

    def snapshot_wellbeings(self, drives: FloatArray) -> list[float]:
        """``snapshot(state)["wellbeing"]`` for each row of ``drives`` (one state's drives
        a row), the same floats: for a reader of every tick that takes them in batches."""
        if self._omega_total == 0:
            return [100.0] * len(drives)
        weighted = np.zeros(len(drives))
        for i, weight in enumerate(self._omega):  # the order of ``_wellbeing``'s sum
            weighted = weighted + weight * drives[:, i]
        values = np.minimum(100.0, np.maximum(0.0, 100.0 - weighted / self._omega_total))
        return [round3(value) for value in values.tolist()]

    def snapshot(self, state: MotivationState) -> dict[str, object]:
        """The ``motivation`` field of DmsState."""
        drives = state.drives.tolist()
        motivations = self._motivations(drives, state.levels.tolist(), state.dominant)
        names = self.names
        return {
            "dominant": None if state.dominant == NO_DOMINANT else names[state.dominant],
            "drives": {name: round3(v) for name, v in zip(names, drives, strict=True)},
            "motivations": {name: round3(v) for name, v in zip(names, motivations, strict=True)},
            "wellbeing": round3(self._wellbeing(drives)),
        }
