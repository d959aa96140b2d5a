"""Long runs of the model in numpy: ``advance`` and the idle robot's days.

``simulate`` gives what calling ``MotivationModel.step`` every ``tick_s`` would give,
without the Python loop: within a window of ticks with the same inputs each drive is
an exact clipped walk (``dynamics.clipped_walk`` over the closed-form change of each
tick, split where the drive turns), and the dominant motivation is found by jumping
from one switch to the next. With ``follow=True`` the running behavior follows the
dominant motivation, as an idle robot does: at each switch the window restarts with
the new behavior's satisfaction. A window also ends at a daylight-saving change, since
``step`` reads the rhythm off the wall clock at the end of each tick.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta

import numpy as np
from numpy.typing import NDArray

from motivation.dynamics import (
    OMEGA,
    TWO_PI,
    FloatArray,
    clipped_walk,
    pieces,
    signed_integrals,
)
from motivation.model import (
    NO_DOMINANT,
    MotivationModel,
    MotivationState,
    day_seconds,
)
from motivation.stimuli import Stimuli

IntArray = NDArray[np.int64]
FIRST_WINDOW = 4096
LARGEST_WINDOW = 1 << 17
SMALLEST_WINDOW = 16


@dataclass(frozen=True)
class Run:
    """The end state and the samples taken every ``every`` ticks (seconds from the start)."""

    final: MotivationState
    end: datetime
    seconds: FloatArray
    drives: FloatArray
    motivations: FloatArray
    dominant: IntArray
    wellbeing: FloatArray
    ticks: int
    switches: int
    """How many times the running behavior changed (with ``follow``)."""


def _turning_intervals(a: float, b: float, peak_s: float, times: FloatArray) -> IntArray:
    """Indexes of the intervals inside which the drive's rate changes sign."""
    if b <= 0.0 or abs(a) >= b:
        return np.zeros(0, dtype=np.int64)
    alpha = math.acos(-a / b)
    theta = OMEGA * (times - peak_s)
    count = np.zeros(len(times) - 1, dtype=np.int64)
    for base in (alpha, -alpha):
        low = np.floor((theta[:-1] - base) / TWO_PI) + 1
        high = np.ceil((theta[1:] - base) / TWO_PI) - 1
        count += np.maximum(0, high - low + 1).astype(np.int64)
    return np.flatnonzero(count)


def drive_path(drive: float, a: float, b: float, peak_s: float, times: FloatArray) -> FloatArray:
    """The drive at ``times[1:]`` from ``drive`` at ``times[0]``, exactly (see module doc)."""
    if a == 0.0 and b == 0.0:  # dormant and nothing taking it down: it stays (as in step)
        return np.full(len(times) - 1, drive, dtype=np.float64)
    changes = signed_integrals(a, b, peak_s, times)
    turning = _turning_intervals(a, b, peak_s, times)
    if turning.size == 0:
        return clipped_walk(drive, changes)
    split = {int(j): pieces(a, b, peak_s, float(times[j]), float(times[j + 1])) for j in turning}
    counts = np.ones(len(changes), dtype=np.int64)
    for j, parts in split.items():
        counts[j] = len(parts)
    refined = np.repeat(changes, counts)
    starts = np.cumsum(counts) - counts
    for j, parts in split.items():
        refined[starts[j] : starts[j] + len(parts)] = parts
    return clipped_walk(drive, refined)[np.cumsum(counts) - 1]


def scan_dominance(
    model: MotivationModel, previous: int, drives: FloatArray, levels: FloatArray
) -> IntArray:
    """The dominant drive after each row of ``drives``; the same rule as ``next_dominant``."""
    table = model.table
    count = len(model.names)
    # column by column: with a handful of drives, n one-dimensional maxima beat one
    # reduction along a short axis
    raw = (drives + table.alpha * levels).T.copy()
    above = (drives >= table.threshold).T.copy()
    held = (drives >= table.release).T.copy()
    masked = np.where(above, raw, -np.inf)
    any_above = functools.reduce(np.logical_or, above)
    out = np.empty(len(drives), dtype=np.int64)
    position, dominant = 0, previous
    while position < len(drives):
        if dominant == NO_DOMINANT:
            found = np.flatnonzero(any_above[position:])
            if found.size == 0:
                out[position:] = NO_DOMINANT
                break
            j = position + int(found[0])
            out[position:j] = NO_DOMINANT
            dominant = int(np.argmax(masked[:, j]))
        else:
            others = [masked[i, position:] for i in range(count) if i != dominant]
            letting_go = ~held[dominant, position:]
            if others:
                best = functools.reduce(np.maximum, others)
                bar = raw[dominant, position:] + model.config.hysteresis
                letting_go |= best > bar
            found = np.flatnonzero(letting_go)
            if found.size == 0:
                out[position:] = dominant
                break
            j = position + int(found[0])
            out[position:j] = dominant
            if held[dominant, j]:  # overtaken by more than the margin
                row = masked[:, j].copy()
                row[dominant] = -np.inf
                dominant = int(np.argmax(row))
            else:
                dominant = int(np.argmax(masked[:, j])) if any_above[j] else NO_DOMINANT
        out[j] = dominant
        position = j + 1
    return out


def motivations_of(
    model: MotivationModel, drives: FloatArray, levels: FloatArray, dominant: IntArray
) -> FloatArray:
    """``M_i`` for each row, with each row's dominant drive held down to its satiation level."""
    table = model.table
    active = drives >= table.threshold
    rows = np.flatnonzero(dominant != NO_DOMINANT)
    columns = dominant[rows]
    active[rows, columns] = drives[rows, columns] >= table.release[columns]
    return np.where(active, drives + table.alpha * levels, 0.0)


OFFSET_PROBE_S = 6 * 3600.0
"""Offsets are probed at least this often inside a window: two daylight-saving
changes are always further apart, so none is missed."""


def _offset(model: MotivationModel, start: datetime, tick_s: float, tick: int) -> float:
    """The zone's UTC offset at the end of tick number ``tick`` (1-based), in seconds."""
    offset = (start + timedelta(seconds=tick * tick_s)).astimezone(model.zone).utcoffset()
    return offset.total_seconds() if offset is not None else 0.0


def _same_offset(
    model: MotivationModel, start: datetime, tick_s: float, position: int, width: int
) -> int:
    """How many ticks from the window's first share its UTC offset.

    ``step`` reads the wall clock at the end of each tick, so across a daylight-saving
    change the rhythm jumps with it; a window stops before the first tick in the new
    offset, and the next window starts there with it.
    """
    offset = _offset(model, start, tick_s, position + 1)
    stride = max(1, int(OFFSET_PROBE_S // tick_s))
    probes = [*range(position + 1 + stride, position + width, stride), position + width]
    low = position + 1  # the last tick known to share the offset
    for tick in probes:
        if _offset(model, start, tick_s, tick) == offset:
            low = tick
            continue
        high: int = tick  # the change is in (low, high]: bisect for its first tick
        while high - low > 1:
            middle = (low + high) // 2
            if _offset(model, start, tick_s, middle) == offset:
                low = middle
            else:
                high = middle
        return high - 1 - position
    return width


def advance(
    model: MotivationModel,
    state: MotivationState,
    duration: float,
    stimuli: Stimuli,
    running: str | None,
    now: datetime,
    tick_s: float = 0.5,
) -> MotivationState:
    """Jump ``duration`` seconds from ``now`` with constant inputs.

    Equals calling ``model.step`` every ``tick_s`` (the dominant motivation is checked at
    each tick, as the daemon does), in closed form and numpy: a month takes about a
    second at 0.5 s ticks.
    """
    run = simulate(model, state, now, duration, stimuli, running=running, tick_s=tick_s, every=0)
    return run.final


def simulate(
    model: MotivationModel,
    state: MotivationState,
    start: datetime,
    duration: float,
    stimuli: Stimuli,
    running: str | None = None,
    follow: bool = False,
    tick_s: float = 0.5,
    every: int = 1,
) -> Run:
    """Run the model from ``start`` for ``duration`` seconds at ``tick_s`` ticks.

    ``running`` is the behavior for the whole run unless ``follow``, where it is the
    dominant motivation's behavior at each tick. ``every`` > 0 keeps one sample every
    that many ticks (0 keeps none). A last partial tick, if any, is one ``step``.
    ``start`` may be in any zone; the ticks are counted in elapsed (UTC) time.
    """
    if tick_s <= 0 or duration < 0:
        raise ValueError(
            f"tick_s must be positive and duration not negative, got {tick_s}, {duration}"
        )
    # ``aware + timedelta`` adds wall-clock time in the datetime's own zone: across a
    # daylight-saving change that is an hour off elapsed time, so count in UTC
    start = start.astimezone(UTC)
    table = model.table
    ticks = int(duration // tick_s)
    drives = np.maximum(0.0, state.drives - stimuli.instant)
    dominant = state.dominant
    levels = stimuli.levels
    current = model.behavior(state) if follow else running
    sampled: list[tuple[FloatArray, FloatArray, IntArray]] = []
    position, window, switches, since_switch = 0, FIRST_WINDOW, 0, 0
    while position < ticks:
        width = min(window, ticks - position)
        width = _same_offset(model, start, tick_s, position, width)
        # the wall clock as step reads it: seconds since local midnight at the end of the
        # window's first tick (small numbers, exact), then tick by tick from there
        first_end = day_seconds(start + timedelta(seconds=(position + 1) * tick_s), model.zone)
        times = (first_end - tick_s) + tick_s * np.arange(width + 1, dtype=np.float64)
        growth, swing = model.net_growth(stimuli, current), model.swing(current)
        block = np.empty((width, len(model.names)), dtype=np.float64)
        for i in range(len(model.names)):
            block[:, i] = drive_path(
                float(drives[i]), float(growth[i]), float(swing[i]), float(table.peak_s[i]), times
            )
        doms = scan_dominance(model, dominant, block, levels)
        accepted, switched = width, False
        if follow:
            names = np.array([*table.behaviors, model.config.idle_behavior])
            changed = np.flatnonzero(names[doms] != current)
            if changed.size:
                accepted, switched = int(changed[0]) + 1, True
        if every > 0:
            index = np.arange(position, position + accepted)
            keep = (index + 1) % every == 0
            sampled.append(
                ((index[keep] + 1) * tick_s, block[:accepted][keep], doms[:accepted][keep])
            )
        drives, dominant = block[accepted - 1].copy(), int(doms[accepted - 1])
        position += accepted
        since_switch += accepted
        if switched:
            switches += 1
            current = model.behavior(MotivationState(drives, levels, dominant))
            # the next behavior likely runs about as long as the last one: a window much
            # longer would mostly be thrown away when switches come every few ticks
            window = min(FIRST_WINDOW, max(SMALLEST_WINDOW, 2 * since_switch))
            since_switch = 0
        else:
            window = min(2 * window, LARGEST_WINDOW)
    final = MotivationState(drives, levels, dominant)
    end = start + timedelta(seconds=ticks * tick_s)
    rest = duration - ticks * tick_s
    if rest > 1e-9 or ticks == 0:  # a run shorter than a tick is one step, even of 0 s
        final = model.step(
            final, rest, stimuli.without_instant(), current, start + timedelta(seconds=duration)
        )
        end = start + timedelta(seconds=duration)
    return _run(model, final, end, sampled, ticks, switches)


def _run(
    model: MotivationModel,
    final: MotivationState,
    end: datetime,
    sampled: list[tuple[FloatArray, FloatArray, IntArray]],
    ticks: int,
    switches: int,
) -> Run:
    width = len(model.names)
    seconds = np.concatenate([s for s, _, _ in sampled]) if sampled else np.zeros(0)
    drives = np.concatenate([d for _, d, _ in sampled]) if sampled else np.zeros((0, width))
    dominant = (
        np.concatenate([m for _, _, m in sampled]) if sampled else np.zeros(0, dtype=np.int64)
    )
    motivations = motivations_of(model, drives, final.levels, dominant)
    wellbeing = model.wellbeings(drives)
    return Run(final, end, seconds, drives, motivations, dominant, wellbeing, ticks, switches)
