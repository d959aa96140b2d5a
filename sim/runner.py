"""``dms sim run``: replay a scenario through the real stack and check its expectations."""

from __future__ import annotations

import random
import time
from dataclasses import dataclass, field
from datetime import datetime, timedelta
from pathlib import Path
from typing import Any

from dms.config import Settings
from dms.kernel import keys
from dms.kernel.messages import (
    DmsState,
    ProfileParams,
    Request,
    RobotCommand,
    ScreenChoice,
    Speech,
    Touch,
    UserPerception,
)
from sim.errors import SimError
from sim.harness import Simulation, TimedDecision
from sim.persona import load_persona
from sim.scenario import Expectation, LoadedScenario, Step, load_scenario, state_field
from sim.user import SimulatedUser


@dataclass
class ExpectationResult:
    index: int
    line: int | None
    description: str
    passed: bool
    detail: str


@dataclass
class ScenarioResult:
    """What a scenario run produced and which expectations held."""

    name: str
    path: Path
    decisions: list[TimedDecision]
    results: list[ExpectationResult]
    ticks: int
    wall_s: float
    errors: list[tuple[float, str, str]] = field(default_factory=list)

    @property
    def passed(self) -> bool:
        return all(result.passed for result in self.results)

    @property
    def first_failure(self) -> ExpectationResult | None:
        return next((result for result in self.results if not result.passed), None)

    def to_json(self) -> dict[str, Any]:
        return {
            "scenario": self.name,
            "file": str(self.path),
            "passed": self.passed,
            "ticks": self.ticks,
            "wall_s": round(self.wall_s, 3),
            "expectations": [
                {
                    "index": r.index,
                    "line": r.line,
                    "expectation": r.description,
                    "passed": r.passed,
                    "detail": r.detail,
                }
                for r in self.results
            ],
            "decisions": [
                {"t": round(d.t, 3), **d.decision.model_dump(mode="json")} for d in self.decisions
            ],
            "errors": [{"t": round(t, 3), "key": k, "error": e} for t, k, e in self.errors],
        }


def _settings(loaded: LoadedScenario) -> Settings:
    return Settings.model_validate(loaded.scenario.settings)


class _Player:
    """Applies timeline steps to a simulation."""

    def __init__(self, sim: Simulation, loaded: LoadedScenario) -> None:
        self.sim = sim
        self.loaded = loaded
        self.rng = random.Random(loaded.scenario.seed)
        self.states: dict[float, DmsState] = {}

    def schedule(self, index: int, step: Step) -> None:
        urgent = step.action in ("say", "tap", "touch", "request")
        self.sim.at(step.at, lambda: self.apply(index, step), urgent=urgent)

    def apply(self, index: int, step: Step) -> None:
        sim = self.sim
        if step.arrive is not None:
            sim.user = None
            sim.presence = UserPerception(
                present=True,
                user_id=step.arrive.user,
                ready=step.arrive.ready,
                engagement=step.arrive.engagement,
            )
            sim.perception_on = True
            sim.feed(keys.PERCEPTION_USER, sim.presence)
        elif step.ready is not None:
            if sim.presence is not None:
                sim.presence = sim.presence.model_copy(update={"ready": step.ready})
                sim.feed(keys.PERCEPTION_USER, sim.presence)
        elif step.leave is not None:
            sim.unseat()
        elif step.say is not None:
            sim.feed(
                keys.PERCEPTION_SPEECH,
                Speech(text=step.say.text, confidence=step.say.confidence),
            )
        elif step.tap is not None:
            sim.feed(keys.PERCEPTION_SCREEN, ScreenChoice(choice=step.tap))
        elif step.touch is not None:
            sim.feed(keys.PERCEPTION_TOUCH, Touch(part=step.touch.part, kind=step.touch.kind))
        elif step.request is not None:
            sim.feed(
                keys.REQUEST,
                Request(
                    action=step.request.action, activity=step.request.activity, by=step.request.by
                ),
            )
        elif step.params is not None:
            if step.params.robot is not None:
                sim.feed(keys.PARAMS_ROBOT, ProfileParams.from_payload(step.params.robot))
            if step.params.env is not None:
                sim.feed(keys.PARAMS_ENV, ProfileParams.from_payload(step.params.env))
        elif step.perception is not None:
            self._perception(step.perception)
        elif step.agenda is not None:
            self._agenda(index, step)
        elif step.visitor is not None:
            persona = load_persona(step.visitor.persona)
            user = SimulatedUser(persona, random.Random(self.rng.random()), step.visitor.user)
            sim.seat(user)
            if step.visitor.minutes is not None:
                sim.at(step.at + step.visitor.minutes * 60, sim.unseat)
        elif step.robot is not None:
            self._robot_fault(index, step)

    def _perception(self, what: str) -> None:
        sim = self.sim
        if what == "stop":
            sim.perception_on = False
        elif what == "resume":
            sim.perception_on = True
            sim.stack.inputs.liveliness(keys.PERCEPTION_USER, True)
        elif what == "lost":
            sim.perception_on = False
            sim.stack.inputs.liveliness(keys.PERCEPTION_USER, False)

    def _where(self, index: int) -> str:
        line = self.loaded.lines.get(("timeline", index))
        return f"{self.loaded.path}:{line}: timeline.{index}"

    def _agenda(self, index: int, step: Step) -> None:
        from sim.adapters import add_agenda_item

        spec = step.agenda
        assert spec is not None
        agenda = self.sim.stack.agenda
        if agenda is None:
            raise SimError(f"{self._where(index)}: agenda: this scenario runs without memory")
        when = self.sim.now() + timedelta(seconds=spec.in_s)
        try:
            add_agenda_item(agenda, spec, when, self.sim.now())
        except SimError as error:
            raise SimError(f"{self._where(index)}: agenda: {error}") from None

    def _robot_fault(self, index: int, step: Step) -> None:
        spec = step.robot
        assert spec is not None
        set_fault = getattr(self.sim.robot, "set_fault", None)
        if set_fault is None:
            raise SimError(f"{self._where(index)}: robot: the simulated robot cannot inject faults")
        set_fault(spec.channel, None if spec.fault == "none" else spec.fault)


def _window(expectation: Expectation, duration: float) -> tuple[float, float]:
    if expectation.within is not None:
        return expectation.within
    return 0.0, duration


def _fmt(timed: TimedDecision) -> str:
    d = timed.decision
    who = f" by {d.chosen_by}" if d.chosen_by else ""
    return f"{timed.t:g}s {d.action} {d.activity or '-'} [{d.reason}{who}]"


def check(
    expectation: Expectation,
    decisions: list[TimedDecision],
    states: dict[float, DmsState],
    duration: float,
    said: list[tuple[float, str]] | None = None,
) -> tuple[bool, str]:
    """Whether one expectation holds, and a sentence saying what was seen."""
    if expectation.resay is not None:
        return _check_resay(expectation, said or [], duration)
    if expectation.state is not None:
        assert expectation.at is not None
        match = expectation.state
        value = _state_at(states, expectation.at, match.field)
        if match.same_as_at is not None:
            before = _state_at(states, match.same_as_at, match.field)
            ok = value == before and value is not None
            return ok, f"{match.field} was {before!r} at {match.same_as_at:g} s, {value!r} now"
        if match.is_null:
            ok = value is None
        elif match.equals is not None:
            ok = value == match.equals
        elif match.one_of is not None:
            ok = value in match.one_of
        elif match.contains is not None:
            ok = isinstance(value, str) and match.contains in value
        elif match.above is not None:
            ok = isinstance(value, int | float) and value > match.above
        else:
            assert match.below is not None
            ok = isinstance(value, int | float) and value < match.below
        return ok, f"{match.field} was {value!r}"
    start, end = _window(expectation, duration)
    in_window = [d for d in decisions if start <= d.t <= end]
    matcher = expectation.decision or expectation.never
    assert matcher is not None
    found = [d for d in in_window if matcher.matches(d.decision)]
    if expectation.never is not None:
        if found:
            return False, f"it happened: {_fmt(found[0])}"
        return True, "did not happen"
    if expectation.count is not None:
        ok = len(found) == expectation.count
        return ok, f"found {len(found)}: " + ("; ".join(_fmt(d) for d in found[:5]) or "none")
    if found:
        return True, f"found {_fmt(found[0])}"
    seen = "; ".join(_fmt(d) for d in in_window[:8]) or "no decision"
    return False, f"not found; in the window: {seen}"


def _check_resay(
    expectation: Expectation, said: list[tuple[float, str]], duration: float
) -> tuple[bool, str]:
    assert expectation.resay is not None
    before = expectation.resay.before
    asked = [text for t, text in said if t < before and "?" in text]
    if not asked:
        return False, f"no question was asked before {before:g} s"
    question = asked[-1]
    start, end = _window(expectation, duration)
    again = [t for t, text in said if start <= t <= end and text.endswith(question)]
    if again:
        return True, f"{question!r} asked again at {again[0]:g} s"
    heard = "; ".join(repr(text) for t, text in said if start <= t <= end)[:300]
    return False, f"{question!r} not asked again; said in the window: {heard or 'nothing'}"


def _state_at(states: dict[float, DmsState], t: float, dotted: str) -> Any:
    """The field in the state after the last tick at or before ``t``."""
    best: DmsState | None = None
    for when in sorted(states):
        if when <= t + 1e-9:
            best = states[when]
        else:
            break
    return state_field(best, dotted) if best is not None else None


def run_scenario(path_or_name: str | Path) -> ScenarioResult:
    """Load a scenario, run it on the virtual clock, check every expectation."""
    loaded = load_scenario(path_or_name)
    scenario = loaded.scenario
    wall = time.perf_counter()
    sim = Simulation(
        _settings(loaded),
        seed=scenario.seed,
        start=scenario.start,
        with_memory=scenario.with_memory,
    )
    sim.idle_step_s = scenario.idle_step_s
    with sim:
        if scenario.profiles:
            from sim.adapters import seed_profile

            for user_id, fields in scenario.profiles.items():
                seed_profile(sim.stack, user_id, dict(fields), sim.now())
        player = _Player(sim, loaded)
        state_times = sorted(
            {e.at for e in scenario.expect if e.at is not None}
            | {e.state.same_as_at for e in scenario.expect if e.state and e.state.same_as_at}
        )
        states: dict[float, DmsState] = {}

        def keep_state(record: Any) -> None:
            states[sim.t] = record.state

        if state_times:
            sim.tick_listeners.append(keep_state)
        said: list[tuple[float, str]] = []

        def keep_speech(command: RobotCommand, _now: datetime) -> None:
            if command.channel == "speech" and command.action == "say":
                said.append((sim.t, str(command.args.get("text", ""))))

        sim.command_listeners.append(keep_speech)
        for index, step in enumerate(scenario.timeline):
            player.schedule(index, step)
        sim.run_until(scenario.duration_s)
        decisions = list(sim.decisions)
        ticks = sim.ticks
        errors = list(sim.errors)
    results = []
    for index, expectation in enumerate(scenario.expect):
        ok, detail = check(expectation, decisions, states, scenario.duration_s, said)
        results.append(
            ExpectationResult(
                index, loaded.expectation_line(index), expectation.describe(), ok, detail
            )
        )
    return ScenarioResult(
        scenario.name, loaded.path, decisions, results, ticks, time.perf_counter() - wall, errors
    )
