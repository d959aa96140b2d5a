"""``dms sim replay``: feed a recording's inputs through the controller again.

The recorded inputs (perception, params, requests) enter a fresh stack (simulated
robot, temporary store) at their recorded times on a virtual clock. The controller
ticks when the recorded daemon ticked (the times of its ``dms/state`` and
``dms/decision`` messages, urgent ticks included), or at 2 Hz when the recording holds
none. The decisions it
takes are compared, in order, with the recorded ``dms/decision`` messages; each
stretch where they differ is reported with its time.

The seed, the settings and the rule, behavior and content files are the recorded
daemon's when the recording holds them (``dms record`` stores them), so a replay needs
no flags; a seed or settings given to :func:`replay` win.
"""

from __future__ import annotations

import bisect
import difflib
import tempfile
import time
from collections import Counter
from dataclasses import dataclass, field
from datetime import UTC, datetime, timedelta
from pathlib import Path, PurePosixPath
from typing import Any

from pydantic import BaseModel, ValidationError

from dms.config import Settings
from dms.inputs import InputRejected, parse_input
from dms.kernel import keys
from dms.kernel.errors import ConfigError
from dms.kernel.messages import Decision
from sim.errors import RecordingError
from sim.recording import RecordedConfig, Recording, read_recording

REPLAYED_INPUTS = frozenset(
    {
        keys.PERCEPTION_USER,
        keys.PERCEPTION_TOUCH,
        keys.PERCEPTION_SPEECH,
        keys.PERCEPTION_SCREEN,
        keys.PARAMS_ROBOT,
        keys.PARAMS_ENV,
        keys.REQUEST,
    }
)

DecisionKey = tuple[str, str | None, str, str | None]


def _key(decision: Decision) -> DecisionKey:
    return (decision.action, decision.activity, decision.reason, decision.chosen_by)


def _describe(decision: Decision) -> str:
    who = f" by {decision.chosen_by}" if decision.chosen_by else ""
    return f"{decision.action} {decision.activity or '-'} [{decision.reason}{who}]"


@dataclass
class Difference:
    """One stretch where the replayed decisions differ from the recorded ones."""

    time: str
    recorded: list[str]
    replayed: list[str]

    def __str__(self) -> str:
        rec = "; ".join(self.recorded) or "nothing"
        rep = "; ".join(self.replayed) or "nothing"
        return f"{self.time}: recorded {rec} | replayed {rep}"


@dataclass
class ReplayReport:
    """How a replay went."""

    file: Path
    inputs: int
    rejected_inputs: int
    ticks: int
    recorded: list[Decision]
    replayed: list[Decision]
    differences: list[Difference]
    truncated: str | None
    wall_s: float
    span_s: float
    notes: list[str] = field(default_factory=list)

    @property
    def same(self) -> bool:
        return not self.differences

    def to_json(self) -> dict[str, Any]:
        return {
            "file": str(self.file),
            "inputs": self.inputs,
            "rejected_inputs": self.rejected_inputs,
            "ticks": self.ticks,
            "span_s": round(self.span_s, 3),
            "recorded_decisions": len(self.recorded),
            "replayed_decisions": len(self.replayed),
            "same": self.same,
            "differences": [
                {"time": d.time, "recorded": d.recorded, "replayed": d.replayed}
                for d in self.differences
            ],
            "truncated": self.truncated,
            "notes": self.notes,
            "wall_s": round(self.wall_s, 3),
        }

    def text(self) -> str:
        lines = [
            f"{self.file}: {self.inputs} inputs over {self.span_s:.1f} s, {self.ticks} ticks; "
            f"{len(self.recorded)} decisions recorded, {len(self.replayed)} replayed"
        ]
        if self.truncated:
            lines.append(f"truncated: {self.truncated}")
        lines.extend(self.notes)
        if self.same:
            lines.append("the replayed decisions are the recorded ones")
        else:
            lines.append(f"{len(self.differences)} difference(s):")
            lines.extend(f"  {difference}" for difference in self.differences)
        return "\n".join(lines)


def _ns_to_dt(ns: int) -> datetime:
    return datetime.fromtimestamp(ns // 1_000_000_000, UTC) + timedelta(
        microseconds=(ns % 1_000_000_000) // 1000
    )


def _parse_time(text: str) -> datetime | None:
    try:
        return datetime.fromisoformat(text.replace("Z", "+00:00"))
    except (ValueError, AttributeError):
        return None


def replay(path: Path, seed: int | None = None, settings: Settings | None = None) -> ReplayReport:
    """Replay ``path``; see the module docstring. ``seed`` and ``settings`` default to the
    recorded daemon's (then to 0 and the defaults, for a recording without them)."""
    recording: Recording = read_recording(path)
    notes: list[str] = []
    config = recording.config
    if config is not None:
        notes.extend(config.warnings)
    with tempfile.TemporaryDirectory(prefix="dms-replay-") as folder:
        if settings is None and config is not None:
            settings = recorded_settings(config, Path(folder))
            notes.append(
                f"the recorded daemon's settings and {len(config.files)} files "
                f"(dms {config.versions.get('dms', '?')})"
            )
        elif settings is None:
            notes.append("no configuration in the recording: the defaults (--config to give it)")
        if seed is None:
            if config is not None and config.seed is not None:
                seed = config.seed
                notes.append(f"the recorded seed {seed}")
            elif settings is not None and settings.seed is not None:
                seed = settings.seed
            else:
                seed = 0
                if config is not None:
                    notes.append("the recorded daemon ran without a seed: its draws differ")
        return _replay(path, recording, seed, settings, notes)


def recorded_settings(config: RecordedConfig, folder: Path) -> Settings:
    """The recorded settings, their files written under ``folder`` and used from there."""
    data = dict(config.settings)
    written: dict[str, Path] = {}
    for name, content in config.files.items():
        relative = PurePosixPath(name)
        if relative.is_absolute() or ".." in relative.parts or len(relative.parts) < 2:
            raise RecordingError(f"a stored file has a name that is not safe: {name!r}")
        if relative.parts[0] == "content":  # searched first beside the behaviors
            relative = PurePosixPath("behaviors", *relative.parts)
        target = folder.joinpath(*relative.parts)
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_bytes(content)
        written[name] = target
    rules = dict(data.get("rules") or {})
    rule_files = sorted(
        (name for name in written if name.startswith("rules/") and name.split("/")[1].isdigit()),
        key=lambda name: int(name.split("/")[1]),
    )
    rules["files"] = [str(written[name]) for name in rule_files]
    schema = [name for name in written if name.startswith("rules/schema/")]
    rules["schema_file"] = str(written[schema[0]]) if schema else None
    data["rules"] = rules
    if any(name.startswith("behaviors/") for name in written):
        data["behaviors"] = {"folder": str(folder / "behaviors")}
    data["db"] = None  # never the recorded store
    try:
        return Settings.model_validate(data)
    except (ValueError, ConfigError) as error:
        first = str(error).splitlines()
        raise RecordingError(
            f"the stored settings are not valid here: {first[0] if first else error}"
        ) from None


def _replay(
    path: Path,
    recording: Recording,
    seed: int,
    settings: Settings | None,
    notes: list[str],
) -> ReplayReport:
    from sim.harness import Simulation

    wall = time.perf_counter()
    inputs: list[tuple[datetime, str, BaseModel]] = []
    recorded: list[Decision] = []
    tick_times: list[datetime] = []
    first_state: dict[str, Any] | None = None
    rejected = 0
    for message in recording.messages:
        at = _ns_to_dt(message.log_time_ns)
        if message.key in REPLAYED_INPUTS:
            try:
                raw = _encode(message.payload)
                inputs.append((at, message.key, parse_input(message.key, raw)))
            except InputRejected:
                rejected += 1  # the daemon rejected it too: it changed nothing
        elif message.key == keys.DMS_DECISION:
            try:
                decision = Decision.model_validate(message.payload)
            except ValidationError:
                notes.append(f"an unreadable decision at {at.isoformat()} was skipped")
                continue
            recorded.append(decision)
            when = _parse_time(decision.time)
            if when is not None:
                tick_times.append(when)  # its tick, even if that tick's state was not recorded
        elif message.key == keys.DMS_STATE and isinstance(message.payload, dict):
            when = _parse_time(str(message.payload.get("time", "")))
            if when is not None:
                tick_times.append(when)
                if first_state is None:
                    first_state = message.payload
    if not inputs and not recorded and not tick_times:
        raise RecordingError(f"{path}: the recording holds no inputs, decisions or states")
    times = [t for t, _, _ in inputs] + tick_times
    times += [t for d in recorded if (t := _parse_time(d.time)) is not None]
    start = min(times)
    end = max(times)
    if not tick_times:
        notes.append("no dms/state in the recording: ticking at 2 Hz")
    sim = Simulation(settings, seed=seed, start=start)
    with sim:
        sim.perception_on = False  # the recorded perception is all there is

        def offset(t: datetime) -> float:
            return max(0.0, (t - start).total_seconds())

        ticks = sorted(set(tick_times))
        urgent = _off_grid(ticks, sim.settings.controller.tick_period_s)
        for at, key, parsed in inputs:
            fed = _feed_time(key, at, ticks, urgent)
            sim.at(offset(fed), lambda k=key, m=parsed: sim.feed(k, m))  # type: ignore[misc]
        if ticks:

            def recorded_tick() -> None:
                sim.tick(False)

            for when in ticks:
                # After the inputs of the same instant (the heap keeps insertion order).
                sim.at(offset(when), recorded_tick)
            sim.periodic = False
        sim.run_until(offset(end) + 0.001)
        replayed = [timed.decision for timed in sim.decisions]
        tick_count = sim.ticks
    replayed = _skip_running_at_start(first_state, recorded, replayed, notes)
    differences = _compare(recorded, replayed)
    return ReplayReport(
        file=path,
        inputs=len(inputs),
        rejected_inputs=rejected,
        ticks=tick_count,
        recorded=recorded,
        replayed=replayed,
        differences=differences,
        truncated=recording.truncated,
        wall_s=time.perf_counter() - wall,
        span_s=(end - start).total_seconds(),
        notes=notes,
    )


URGENT_WINDOW = timedelta(milliseconds=150)
"""How far apart the recorder may log an urgent input and the daemon tick on it.

Both receive the same sample; the daemon ticks at once on an urgent input (touch,
speech, screen, request), and the recorder logs it at about the same time, before or
after that tick by the two processes' lag (tens of milliseconds on a loaded machine).
Such a tick is off the loop's 2 Hz grid (the loop ticks against monotonic deadlines, so
its regular ticks keep one phase): the input is fed at the off-grid tick nearest to its
log time within this window (before it, if the tick came first), else at the nearest
tick within it. Other inputs wait for the next tick after them, as in the daemon.
"""

GRID_SLACK_S = 0.03
"""A tick further than this from the regular ticks' phase is an urgent one."""


def _off_grid(ticks: list[datetime], period_s: float) -> set[datetime]:
    """The ticks off the phase most ticks share: those urgent inputs started."""
    if not ticks:
        return set()
    phases = [t.timestamp() % period_s for t in ticks]
    # the phase most ticks share, to 10 ms
    mode = Counter(round(phase, 2) for phase in phases).most_common(1)[0][0]

    def distance(phase: float) -> float:
        d = abs(phase - mode) % period_s
        return min(d, period_s - d)

    return {t for t, phase in zip(ticks, phases, strict=True) if distance(phase) > GRID_SLACK_S}


def _feed_time(key: str, at: datetime, ticks: list[datetime], urgent: set[datetime]) -> datetime:
    """When to feed an input logged at ``at``, given the recorded tick times and which
    of them are off the grid (see :data:`URGENT_WINDOW`)."""
    if key not in keys.URGENT_INPUTS:
        return at
    low = bisect.bisect_left(ticks, at - URGENT_WINDOW)
    high = bisect.bisect_right(ticks, at + URGENT_WINDOW)
    near = ticks[low:high]
    pool = [t for t in near if t in urgent] or near
    if not pool:
        return at
    tick = min(pool, key=lambda t: (abs((t - at).total_seconds()), t < at))
    return at if tick >= at else tick


def _skip_running_at_start(
    first_state: dict[str, Any] | None,
    recorded: list[Decision],
    replayed: list[Decision],
    notes: list[str],
) -> list[Decision]:
    """Leave out the replay's start of what already ran when the recording began.

    A recording that starts while an activity runs holds no decision for it; the fresh
    controller of the replay decides to start it at its first tick. That start is the
    recording's initial state, not a difference.
    """
    activity = (first_state or {}).get("activity")
    if not isinstance(activity, dict) or not replayed:
        return replayed
    name = activity.get("name")
    first = replayed[0]
    recorded_start = any(d.action == "start" and d.activity == name for d in recorded[:1])
    if first.action == "start" and first.activity == name and not recorded_start:
        notes.append(f"the recording starts while {name} runs: its start is not compared")
        return replayed[1:]
    return replayed


def _encode(payload: Any) -> bytes:
    import json

    return json.dumps(payload).encode()


def _compare(recorded: list[Decision], replayed: list[Decision]) -> list[Difference]:
    matcher = difflib.SequenceMatcher(
        a=[_key(d) for d in recorded], b=[_key(d) for d in replayed], autojunk=False
    )
    out: list[Difference] = []
    for tag, a0, a1, b0, b1 in matcher.get_opcodes():
        if tag == "equal":
            continue
        when = recorded[a0].time if a0 < len(recorded) else replayed[b0].time
        out.append(
            Difference(
                when,
                [f"{d.time[11:23]} {_describe(d)}" for d in recorded[a0:a1]],
                [f"{d.time[11:23]} {_describe(d)}" for d in replayed[b0:b1]],
            )
        )
    return out
