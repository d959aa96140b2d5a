"""Scenarios: a scripted session on the virtual clock, and what must come of it.

A scenario file (YAML) has a ``timeline`` of inputs at seconds from the start and
a list of expectations::

    name: shoulder_stop
    seed: 3
    duration_s: 120
    settings: {controller: {feedback_probability: 0}}   # merged into dms.config.Settings
    timeline:
      - {at: 0, arrive: {user: alice}}
      - {at: 5, say: "let's play the quiz"}
      - {at: 30, touch: right_shoulder}
      - {at: 33, say: stop}
    expect:
      - {decision: {action: start, activity: quiz, reason: user_request}, within: [5, 6]}
      - {state: {field: activity.name, equals: null}, at: 40}
      - {never: {reason: motivation_changed}}

``profiles`` stores profile fields before the run. Each timeline step does one
thing: ``arrive``, ``ready``, ``leave``, ``say``, ``tap``,
``touch``, ``request``, ``params``, ``perception`` (``stop``: the perception module
stops publishing, so its input goes stale; ``lost``: its liveliness token goes away;
``resume``), ``agenda`` (add a reminder or event), ``visitor`` (a persona acts by
itself) or ``robot`` (make the simulated robot fail or hang on a channel).
"""

from __future__ import annotations

from datetime import UTC, datetime
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from dms.config import Settings
from dms.kernel.activity_names import ACTIVITIES, current
from dms.kernel.messages import Decision, DmsState
from dms.kernel.yamlfile import Path_
from sim.errors import SpecError
from sim.specfile import load_spec, read_yaml, validate

SCENARIO_DIR = Path(__file__).parent / "scenarios"
Seconds = Annotated[float, Field(ge=0.0, le=366 * 86400)]
UserId = Annotated[str, Field(pattern=r"^[A-Za-z0-9_-]{1,64}$")]


def _known_activity(value: str | None) -> str | None:
    """An activity of the catalogue in force: the shipped ones and those the scenario's
    behaviors folder declares (:func:`load_scenario` installs it before validating)."""
    if value is not None and value not in ACTIVITIES:
        raise ValueError(current().unknown(value))
    return value


class _Spec(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Arrive(_Spec):
    user: UserId
    ready: bool = True
    engagement: Annotated[float, Field(ge=0.0, le=1.0)] | None = None


class TouchSpec(_Spec):
    part: Literal["right_shoulder", "left_shoulder", "head", "belly"] = "right_shoulder"
    kind: Literal["tap", "caress", "hit"] = "tap"

    @model_validator(mode="before")
    @classmethod
    def _from_part(cls, value: object) -> object:
        return {"part": value} if isinstance(value, str) else value


class SaySpec(_Spec):
    text: str = Field(min_length=1, max_length=4096)
    confidence: Annotated[float, Field(ge=0.0, le=1.0)] = 0.9

    @model_validator(mode="before")
    @classmethod
    def _from_text(cls, value: object) -> object:
        return {"text": value} if isinstance(value, str) else value


class RequestSpec(_Spec):
    action: Literal["start", "cancel", "pause", "resume", "reload_rules"]
    activity: str | None = None
    by: str | None = "scenario"

    _known = field_validator("activity")(_known_activity)


ParamValue = str | bool | int | float


class ParamsSpec(_Spec):
    robot: dict[str, ParamValue] | None = None
    env: dict[str, ParamValue] | None = None


class AgendaSpec(_Spec):
    """An agenda item added at this step; it falls due ``in_s`` seconds later."""

    kind: Literal["reminder", "event"] = "reminder"
    user: UserId
    in_s: Seconds = 0.0
    text: str | None = None
    activity: str | None = None
    priority: Literal["normal", "high"] = "normal"

    _known = field_validator("activity")(_known_activity)


class VisitorSpec(_Spec):
    persona: str
    user: UserId | None = None
    minutes: Annotated[float, Field(gt=0.0)] | None = None
    """Leave after this long (None: stay until the end)."""


class RobotFaultSpec(_Spec):
    """Make the simulated robot misbehave on a channel from now on."""

    channel: Literal["speech", "screen", "led", "motion", "media", "aim"]
    fault: Literal["fail", "hang", "none"] = "fail"


class Step(_Spec):
    """One timeline entry: at ``at`` seconds, do exactly one thing."""

    at: Seconds
    arrive: Arrive | None = None
    ready: bool | None = None
    leave: bool | None = None
    say: SaySpec | None = None
    tap: str | None = Field(default=None, min_length=1, max_length=256)
    touch: TouchSpec | None = None
    request: RequestSpec | None = None
    params: ParamsSpec | None = None
    perception: Literal["stop", "lost", "resume"] | None = None
    agenda: AgendaSpec | None = None
    visitor: VisitorSpec | None = None
    robot: RobotFaultSpec | None = None

    @model_validator(mode="after")
    def _one_thing(self) -> Step:
        done = [name for name in _ACTIONS if getattr(self, name) is not None]
        if len(done) != 1:
            what = ", ".join(done) if done else "nothing"
            raise ValueError(f"a step does exactly one of {', '.join(_ACTIONS)}; this one: {what}")
        return self

    @property
    def action(self) -> str:
        return next(name for name in _ACTIONS if getattr(self, name) is not None)


_ACTIONS = (
    "arrive",
    "ready",
    "leave",
    "say",
    "tap",
    "touch",
    "request",
    "params",
    "perception",
    "agenda",
    "visitor",
    "robot",
)


class DecisionMatch(_Spec):
    """Fields a decision must have (those given)."""

    action: Literal["start", "pause", "resume", "cancel", "complete", "fail", "ask"] | None = None
    activity: str | None = None
    reason: str | None = None
    chosen_by: Literal["robot", "user", "agenda", "motivation"] | None = None
    detail_contains: str | None = None

    def matches(self, decision: Decision) -> bool:
        return (
            (self.action is None or decision.action == self.action)
            and (self.activity is None or decision.activity == self.activity)
            and (self.reason is None or decision.reason == self.reason)
            and (self.chosen_by is None or decision.chosen_by == self.chosen_by)
            and (
                self.detail_contains is None
                or self.detail_contains.lower() in (decision.detail or "").lower()
            )
        )

    def describe(self) -> str:
        parts = [
            f"{name}={value}" for name, value in self.model_dump().items() if value is not None
        ]
        return "decision " + (" ".join(parts) or "(any)")


class StateMatch(_Spec):
    """A DmsState field (dotted path) and what it must be."""

    field: str = Field(pattern=r"^[a-z_]+(\.[a-z_/]+)*$")
    equals: Any = None
    one_of: list[Any] | None = None
    contains: str | None = None
    above: float | None = None
    below: float | None = None
    same_as_at: Seconds | None = None
    """The field must have the value it had at this earlier time."""
    is_null: bool | None = None

    @model_validator(mode="before")
    @classmethod
    def _null_equals(cls, value: object) -> object:
        # ``equals: null`` means "must be null": keep that apart from "equals not given".
        if isinstance(value, dict) and "equals" in value and value["equals"] is None:
            value = {k: v for k, v in value.items() if k != "equals"}
            value["is_null"] = True
        return value

    @model_validator(mode="after")
    def _one_test(self) -> StateMatch:
        tests = [
            name
            for name in ("equals", "one_of", "contains", "above", "below", "same_as_at", "is_null")
            if getattr(self, name) is not None
        ]
        if len(tests) != 1:
            raise ValueError(
                "give exactly one of equals, one_of, contains, above, below, same_as_at"
            )
        return self

    def describe(self) -> str:
        for name in ("equals", "one_of", "contains", "above", "below", "same_as_at"):
            value = getattr(self, name)
            if value is not None:
                return f"state {self.field} {name} {value!r}"
        return f"state {self.field} is null"


class ResayMatch(_Spec):
    """The last question the robot asked before ``before`` is asked again in the window."""

    before: Seconds


class Expectation(_Spec):
    """One of: ``decision`` (happens in ``within``), ``never`` (does not), ``state`` at
    ``at``, ``resay`` (a question asked again in ``within``)."""

    decision: DecisionMatch | None = None
    never: DecisionMatch | None = None
    state: StateMatch | None = None
    resay: ResayMatch | None = None
    within: tuple[Seconds, Seconds] | None = None
    at: Seconds | None = None
    count: Annotated[int, Field(ge=0)] | None = None
    """With ``decision``: exactly this many in the window (default: at least one)."""
    name: str | None = None

    @model_validator(mode="after")
    def _one_kind(self) -> Expectation:
        kinds = [k for k in ("decision", "never", "state", "resay") if getattr(self, k) is not None]
        if len(kinds) != 1:
            raise ValueError("an expectation is exactly one of decision, never, state, resay")
        if self.state is not None and self.at is None:
            raise ValueError("a state expectation needs 'at' (seconds)")
        if self.within is not None and self.within[1] < self.within[0]:
            raise ValueError("within: the end is before the start")
        return self

    def describe(self) -> str:
        window = f" within {self.within[0]:g}-{self.within[1]:g} s" if self.within else ""
        if self.state is not None:
            text = f"{self.state.describe()} at {self.at:g} s"
        elif self.resay is not None:
            text = f"the question asked before {self.resay.before:g} s is asked again{window}"
        else:
            match = self.decision or self.never
            assert match is not None
            window = f" within {self.within[0]:g}-{self.within[1]:g} s" if self.within else ""
            count = f" {self.count} times" if self.count is not None else ""
            prefix = "no " if self.never is not None else ""
            text = f"{prefix}{match.describe()}{count}{window}"
        return f"{self.name}: {text}" if self.name else text


class Scenario(_Spec):
    """A scripted session."""

    name: str
    description: str = ""
    seed: int = 0
    start: datetime = datetime(2026, 11, 23, 10, 0, tzinfo=UTC)
    duration_s: Annotated[float, Field(gt=0.0, le=7 * 86400)] = 120.0
    settings: dict[str, Any] = Field(default_factory=dict)
    """Merged over the simulation's defaults, then validated as dms.config.Settings."""
    with_memory: bool = True
    idle_step_s: Annotated[float, Field(gt=0.0, le=3600.0)] | None = None
    """Tick this far apart while nobody is there (long idle scenarios; see sim.harness)."""
    profiles: dict[UserId, dict[str, ParamValue]] = Field(default_factory=dict)
    """Profile fields stored before the run (e.g. ``alice: {proactivity: high}``)."""
    timeline: list[Step] = Field(default_factory=list)
    expect: list[Expectation] = Field(default_factory=list)

    @field_validator("start")
    @classmethod
    def _aware(cls, value: datetime) -> datetime:
        if value.tzinfo is None:
            raise ValueError("give a time zone (e.g. 2026-11-23T10:00:00Z)")
        return value.astimezone(UTC)

    @field_validator("settings")
    @classmethod
    def _valid_settings(cls, value: dict[str, Any]) -> dict[str, Any]:
        Settings.model_validate(value)
        return value


class LoadedScenario(BaseModel):
    """A scenario and where its parts are in the file (for messages)."""

    model_config = ConfigDict(arbitrary_types_allowed=True, frozen=True)

    scenario: Scenario
    path: Path
    lines: dict[Path_, int]

    def expectation_line(self, index: int) -> int | None:
        return self.lines.get(("expect", index))


def scenario_path(name_or_path: str) -> Path:
    """A shipped scenario by name or a path to a YAML file."""
    candidate = Path(name_or_path)
    if candidate.suffix in (".yaml", ".yml") or candidate.exists():
        return candidate
    shipped = SCENARIO_DIR / f"{name_or_path}.yaml"
    if shipped.exists():
        return shipped
    return candidate


def load_scenario(name_or_path: str | Path) -> LoadedScenario:
    """Load and validate a scenario; SpecError names file, line and field."""
    path = name_or_path if isinstance(name_or_path, Path) else scenario_path(name_or_path)
    data, lines = read_yaml(path)
    _install_catalogue(data, lines, path)
    scenario = validate(Scenario, data, lines, str(path))
    for index, step in enumerate(scenario.timeline):
        if step.at > scenario.duration_s:
            line = lines.get(("timeline", index))
            raise SpecError(
                f"{path}:{line}: timeline.{index}.at: {step.at:g} s is after duration_s "
                f"{scenario.duration_s:g}"
            )
    return LoadedScenario(scenario=scenario, path=path, lines=lines)


def _install_catalogue(data: Any, lines: dict[Path_, int], path: Path) -> None:
    """Put in force the activities of the behaviors folder the scenario's settings name
    (the shipped ones without one), as the simulated daemon will: its timeline and
    expectations may name a declared activity. A folder that is missing or does not
    load is refused with its first problem."""
    from activities.errors import BehaviorError
    from activities.library import BehaviorLibrary

    settings = data.get("settings") if isinstance(data, dict) else None
    behaviors = settings.get("behaviors") if isinstance(settings, dict) else None
    folder = behaviors.get("folder") if isinstance(behaviors, dict) else None
    where = Path(folder) if isinstance(folder, str) else None
    line = lines.get(("settings", "behaviors", "folder"))
    at = f"{path}:{line}" if line is not None else str(path)
    if where is not None and not where.is_dir():
        raise SpecError(f"{at}: settings.behaviors.folder: {where} is not a directory")
    try:
        BehaviorLibrary.load(where).install_catalogue()
    except BehaviorError as error:
        raise SpecError(f"{at}: settings.behaviors.folder: {error}") from None


def shipped_scenarios() -> list[Path]:
    """The scenario files that ship with the project."""
    return sorted(SCENARIO_DIR.glob("*.yaml"))


def state_field(state: DmsState, dotted: str) -> Any:
    """The value at a dotted path of a DmsState (``activity.name``, ``motivation.drives.rest``)."""
    value: Any = state.model_dump(mode="json")
    for part in dotted.split("."):
        if not isinstance(value, dict):
            return None
        value = value.get(part)
    return value


__all__ = ["Expectation", "LoadedScenario", "Scenario", "Step", "load_scenario", "load_spec"]
