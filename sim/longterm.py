"""``dms sim longterm``: weeks of robot life, users visiting on their schedules.

The robot runs on the virtual clock day and night. Each user (a shipped persona,
taken in order) visits on the days and at the times of its persona, a little earlier
or later each time; two visits never overlap (the later one waits). Each user has a
daily reminder in the agenda ten minutes after the time of their first visit; it
waits up to two hours for them to be there.

While someone is in front of the robot, or a dialog is open, the controller ticks at
2 Hz as in the daemon. While nobody is there it ticks every ``idle_step_s`` (5 min)
instead, and at once at an arrival, and at the very 2 Hz tick where the motivated
behavior changes (the motivation model is exact over any step and tells when): the
idle behaviors (sleep, wait, calling for attention) only react to the motivation, and
the agenda fires only for a present user, so the motivation's decisions fall on the
same ticks as at 2 Hz (tests/sim/test_idle_steps.py); only the inside of an idle
activity is seen less often. ``ticks`` in the JSON counts the controller ticks run.
"""

from __future__ import annotations

import random
import resource
import sys
import time
from collections import defaultdict
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from dms.config import Settings
from dms.kernel.messages import RobotCommand
from motivation.dynamics import FloatArray
from motivation.model import MotivationModel
from sim.persona import WEEKDAYS, Persona, load_persona, shipped_personas
from sim.study import DecisionRow, SessionMetrics, SessionObserver, command_handle
from sim.user import SimulatedUser

if TYPE_CHECKING:
    from dms.controller import TickRecord
    from sim.harness import Simulation, TimedDecision

IDLE_STEP_S = 300.0
SAMPLE_EVERY_S = 300.0
START = datetime(2026, 11, 23, 0, 0, tzinfo=UTC)  # a Monday


@dataclass(frozen=True, slots=True)
class PlannedVisit:
    user: int
    start_s: float
    end_s: float


def plan_visits(personas: list[Persona], days: int, rng: random.Random) -> list[PlannedVisit]:
    """Every visit of every user over ``days``, in time order, never overlapping."""
    raw: list[PlannedVisit] = []
    for day in range(days):
        weekday = WEEKDAYS[(START + timedelta(days=day)).weekday()]
        for index, persona in enumerate(personas):
            for visit in persona.visits:
                if weekday not in visit.weekdays():
                    continue
                at = float(day * 86400 + visit.at.hour * 3600 + visit.at.minute * 60)
                at += rng.uniform(-visit.jitter_min, visit.jitter_min) * 60
                length = visit.minutes * 60 * rng.uniform(0.8, 1.2)
                raw.append(PlannedVisit(index, max(0.0, at), max(0.0, at) + length))
    raw.sort(key=lambda v: v.start_s)
    planned: list[PlannedVisit] = []
    free_at = 0.0
    for wanted in raw:
        start = max(wanted.start_s, free_at)
        end = start + (wanted.end_s - wanted.start_s)
        if start >= days * 86400:
            continue
        planned.append(PlannedVisit(wanted.user, start, min(end, days * 86400.0)))
        free_at = end + 120.0
    return planned


@dataclass
class LongtermResult:
    days: int
    users: list[str]
    ticks: int
    wall_s: float
    drives_max: dict[str, float]
    wellbeing_mean: float
    activity_seconds: dict[str, float]
    activity_seconds_by_hour: dict[str, dict[str, float]]
    peak_rss_mb: float
    visits: int
    decisions: int
    samples: list[tuple[float, dict[str, float], float]] = field(repr=False)
    spans: list[tuple[str, float, float]] = field(repr=False)
    presence: list[tuple[int, float, float]] = field(repr=False, default_factory=list)
    """(user index, arrival, departure) of every visit, in seconds from the start."""
    plots: list[Path] = field(default_factory=list)
    sessions: list[SessionMetrics] = field(default_factory=list)
    """Table 4's metrics of each visit (``sessions.csv``)."""
    decision_rows: list[DecisionRow] = field(default_factory=list)
    """The decisions taken during visits (``decisions.csv``)."""

    def to_json(self) -> dict[str, Any]:
        return {
            "days": self.days,
            "ticks": self.ticks,
            "wall_s": round(self.wall_s, 3),
            "drives_max": {k: round(v, 3) for k, v in self.drives_max.items()},
            "wellbeing_mean": round(self.wellbeing_mean, 3),
            "activity_seconds": {k: round(v, 1) for k, v in sorted(self.activity_seconds.items())},
            "activity_seconds_by_hour": {
                hour: {k: round(v, 1) for k, v in sorted(names.items())}
                for hour, names in self.activity_seconds_by_hour.items()
            },
            "peak_rss_mb": round(self.peak_rss_mb, 1),
            "users": self.users,
            "visits": self.visits,
            "decisions": self.decisions,
            "plots": [str(path) for path in self.plots],
        }


class _Tracker:
    """Accounts the time of each activity, by hour of day, and samples the drives.

    A shortcut, for the 30-day run's wall time: it reads the motivation model's own
    state each tick, not the snapshot of DmsState (a pydantic model), and sums the
    drives and the wellbeing in numpy batches of :data:`BATCH_TICKS` ticks. Reading the
    snapshot tick by tick made the run take 1.7 times as long (29.7 s of CPU against
    17.9 s, measured). The numbers are the snapshot's: it rounds the state to three
    places, and rounding keeps the order, so the largest rounded drive is the rounded
    largest one (``drives_max``); the wellbeing is rounded the same way. Samples take
    the snapshot itself.
    """

    BATCH_TICKS = 4096

    def __init__(self, start: datetime, model: MotivationModel) -> None:
        self.start = start
        self.model = model
        self.last_t: float | None = None
        self.last_activity: str | None = None
        self.activity_seconds: dict[str, float] = defaultdict(float)
        self.by_hour: dict[int, dict[str, float]] = {h: defaultdict(float) for h in range(24)}
        self._drives_max: FloatArray | None = None
        """The largest value of each drive (the model's order), not rounded yet."""
        self._wellbeing_area = 0.0
        self._last_wellbeing: float | None = None
        self._summed_t: float | None = None
        """The last tick summed and its wellbeing: the area runs on from there."""
        self._times: list[float] = []
        self._drives: list[FloatArray | None] = []
        """Each tick's time and drives (None before the first step), not summed yet."""
        self.samples: list[tuple[float, dict[str, float], float]] = []
        self.next_sample = 0.0
        self.spans: list[tuple[str, float, float]] = []
        self._span_start = 0.0
        self._base = start.hour * 3600 + start.minute * 60 + start.second

    @property
    def drives_max(self) -> dict[str, float]:
        """The largest value of each drive, as the snapshots give them (rounded)."""
        self._sum()
        if self._drives_max is None:  # no step yet: the snapshot had no drives
            return {}
        names = self.model.names
        highest = self._drives_max.tolist()
        return {name: round(value, 3) for name, value in zip(names, highest, strict=True)}

    @property
    def wellbeing_area(self) -> float:
        """The wellbeing integrated over the time ticked (each tick's until the next)."""
        self._sum()
        return self._wellbeing_area

    def on_tick(self, t: float, record: TickRecord) -> None:
        state = record.motivation_state
        self._times.append(t)
        self._drives.append(None if state is None else state.drives)
        if len(self._times) >= self.BATCH_TICKS:
            self._sum()
        activity = record.activity
        if activity != self.last_activity:
            self._end_span(t)
            self._span_start = t
        self.last_activity = activity
        self.last_t = t
        if t >= self.next_sample:
            motivation = record.motivation
            self.samples.append((t, dict(motivation.drives), motivation.wellbeing))
            self.next_sample = t + SAMPLE_EVERY_S

    def _sum(self) -> None:
        """Fold the ticks noted since the last call into the area and the maxima."""
        times, noted = self._times, self._drives
        if not times:
            return
        stepped = [drives for drives in noted if drives is not None]
        wellbeings: list[float] = []
        if stepped:
            rows = np.array(stepped)
            highest = rows.max(axis=0)
            if self._drives_max is not None:
                highest = np.maximum(highest, self._drives_max)
            self._drives_max = highest
            wellbeings = [round(w, 3) for w in self.model.wellbeings(rows).tolist()]
        # before the first step the snapshot says 100 (no drives); steps come after it
        wellbeings = [100.0] * (len(noted) - len(stepped)) + wellbeings
        area, last, previous = self._wellbeing_area, self._last_wellbeing, self._summed_t
        for t, wellbeing in zip(times, wellbeings, strict=True):
            if last is not None and previous is not None:  # each tick's until the next
                area += last * (t - previous)
            last, previous = wellbeing, t
        self._wellbeing_area, self._last_wellbeing, self._summed_t = area, last, previous
        times.clear()
        noted.clear()

    def _end_span(self, t1: float) -> None:
        """The activity running since ``_span_start`` (if any) ends at ``t1``: its span is
        kept and its time added, split at the hours of the day."""
        name, t0 = self.last_activity, self._span_start
        if name is None:
            return
        self.spans.append((name, t0, t1))
        self.activity_seconds[name] += t1 - t0
        base = self._base
        t = t0
        while t < t1:
            clock = base + t
            boundary = (clock // 3600 + 1) * 3600 - base
            end = min(t1, boundary)
            self.by_hour[int(clock // 3600) % 24][name] += end - t
            t = end

    def finish(self, t: float) -> None:
        self._sum()
        self._end_span(t)


def _peak_rss_mb() -> float:
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / (1024 * 1024) if sys.platform == "darwin" else peak / 1024


def run_longterm(
    days: int = 30,
    users: int = 3,
    seed: int = 0,
    out: Path | None = None,
    settings: Settings | None = None,
    progress: Callable[[int], None] | None = None,
    idle_step_s: float = IDLE_STEP_S,
) -> LongtermResult:
    """Simulate ``days`` of robot life with ``users`` visitors; plots go to ``out``."""
    from sim.adapters import daily_reminder, ensure_user
    from sim.harness import Simulation

    wall = time.perf_counter()
    rng = random.Random(seed)
    names = [name for name in shipped_personas() if name != "demo"]
    personas = [load_persona(names[i % len(names)]) for i in range(users)]
    ids = [
        persona.id if i < len(names) else f"{persona.id}{i // len(names) + 1}"
        for i, persona in enumerate(personas)
    ]
    visits = plan_visits(personas, days, rng)
    with Simulation(settings, seed=seed, start=START) as sim:
        sim.idle_step_s = idle_step_s
        tracker = _Tracker(START, sim.controller.deps.motivation)
        sim.tick_listeners.append(lambda record: tracker.on_tick(sim.t, record))
        people = [
            SimulatedUser(persona, random.Random(rng.random()), user_id)
            for persona, user_id in zip(personas, ids, strict=True)
        ]
        if sim.stack.agenda is not None:
            for persona, user_id in zip(personas, ids, strict=True):
                ensure_user(sim.stack, user_id, START)
                if persona.visits:
                    first = persona.visits[0].at
                    minute = first.hour * 60 + first.minute + 10
                    daily_reminder(sim.stack.agenda, user_id, minute // 60 % 24, minute % 60, START)
        visiting = _Visits(sim)
        for visit in visits:
            person = people[visit.user]
            sim.at(visit.start_s, lambda p=person: visiting.seat(p))  # type: ignore[misc]
            sim.at(visit.end_s, visiting.unseat)
        for day in range(1, days + 1):
            sim.run_until(day * 86400.0)
            if progress is not None:
                progress(day)
        tracker.finish(sim.t)
        ticks, decisions = sim.ticks, len(sim.decisions)
    wellbeing_mean = tracker.wellbeing_area / max(1e-9, tracker.last_t or 1e-9)
    result = LongtermResult(
        days=days,
        users=ids,
        ticks=ticks,
        wall_s=time.perf_counter() - wall,
        drives_max=dict(tracker.drives_max),
        wellbeing_mean=wellbeing_mean,
        activity_seconds=dict(tracker.activity_seconds),
        activity_seconds_by_hour={
            str(hour): {k: v for k, v in names_.items() if v > 0}
            for hour, names_ in tracker.by_hour.items()
        },
        peak_rss_mb=_peak_rss_mb(),
        visits=len(visits),
        decisions=decisions,
        samples=tracker.samples,
        spans=tracker.spans,
        presence=[(v.user, v.start_s, v.end_s) for v in visits],
        sessions=visiting.sessions,
        decision_rows=visiting.rows,
    )
    if out is not None:
        from sim.export import write_all
        from sim.plots import write_plots

        result.plots = write_plots(result, out)
        result.plots += write_all(out, result.sessions, result.decision_rows)
    return result


class _Visits:
    """Seats and unseats the visitors, measuring each visit as a study session."""

    def __init__(self, sim: Simulation) -> None:
        self.sim = sim
        self.sessions: list[SessionMetrics] = []
        self.rows: list[DecisionRow] = []
        self.visits: dict[str, int] = {}
        self.observer: SessionObserver | None = None
        self.user: SimulatedUser | None = None
        self.t0 = 0.0
        self.misrecognized = 0
        sim.decision_listeners.append(self._on_decision)
        sim.command_listeners.append(self._on_command)
        sim.tick_listeners.append(lambda _record: self._on_tick())

    def _on_decision(self, timed: TimedDecision) -> None:
        if self.observer is None or self.user is None:
            return
        self.observer.on_decision(timed)
        visit = self.visits[self.user.user_id]
        number = len(self.sessions) + 1
        row = DecisionRow(number, self.user.user_id, visit, timed.t - self.t0, timed.decision)
        self.rows.append(row)

    def _on_command(self, command: RobotCommand, _now: datetime) -> None:
        if self.observer is not None:
            self.observer.on_command(command_handle(self.sim, command), self.sim.t)

    def _on_tick(self) -> None:
        if self.observer is not None:
            self.observer.on_tick(self.sim.t)

    def seat(self, user: SimulatedUser) -> None:
        self._finish()
        self.user, self.observer, self.t0 = user, SessionObserver(), self.sim.t
        self.visits[user.user_id] = self.visits.get(user.user_id, 0) + 1
        self.misrecognized = user.stats.misrecognized
        self.sim.seat(user)

    def unseat(self) -> None:
        self.sim.unseat()
        self._finish()

    def _finish(self) -> None:
        user, observer = self.user, self.observer
        if user is None or observer is None:
            return
        metrics = observer.metrics
        metrics.participant, metrics.visit = user.user_id, self.visits[user.user_id]
        metrics.misrecognized = user.stats.misrecognized - self.misrecognized
        self.sessions.append(metrics)
        self.user = self.observer = None
