"""The ``[motivation]`` section of the daemon's TOML: drives, stimuli, hysteresis.

Read once at start-up (and by ``dms motivation plot``). Every number has a range;
a value out of range, an unknown field or an unknown behavior is refused with one
line naming the field, e.g. ``motivation.drives.rest.threshold: Input should be
less than or equal to 100``. A drive named like a default one inherits the default's
fields, so ``[motivation.drives.rest] threshold = 70`` changes only the threshold.
"""

from __future__ import annotations

from difflib import get_close_matches
from typing import Any, Literal, get_args, get_origin

import annotated_types
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    ValidationInfo,
    field_validator,
    model_validator,
)
from pydantic.fields import FieldInfo
from pydantic_core import ErrorDetails

from dms.kernel.activity_names import ACTIVITIES

StimulusSource = Literal["user", "darkness", "quiet", "caress", "music"]
"""What perception can excite: a user present and engaged, a dark room, a quiet
room, a caress on a touch sensor, music playing."""

STIMULUS_SOURCES: tuple[StimulusSource, ...] = ("user", "darkness", "quiet", "caress", "music")


class MotivationConfigError(ValueError):
    """A ``[motivation]`` value is wrong; the message is one line naming the field."""


def _known_behavior(name: str) -> str:
    """A drive's behavior is an activity of the catalogue in force: the shipped ones and
    those the behaviors folder declares (the daemon installs it before reading this)."""
    if name not in ACTIVITIES:
        close = get_close_matches(name, list(ACTIVITIES), n=1)
        hint = f"did you mean {close[0]}?" if close else f"one of {', '.join(ACTIVITIES)}"
        raise ValueError(f"unknown behavior {name!r}; {hint}")
    return name


class DriveConfig(BaseModel):
    """One drive: a deficit in [0, 100] that grows over the day and falls while satisfied."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    enabled: bool = True
    """False removes a default drive."""
    rate_per_hour: float = Field(ge=0, le=100)
    """Mean growth in points per hour."""
    amplitude: float = Field(default=0.0, ge=0, le=1)
    """Daily modulation of the rate: it runs from (1 - amplitude) to (1 + amplitude) times it."""
    peak_hour: float = Field(default=0.0, ge=0, lt=24)
    """Local hour at which the rate is highest (for rest: the middle of the night)."""
    threshold: float = Field(ge=0, le=100)
    """L_d: below it the drive gives no motivation."""
    satiation: float | None = Field(default=None, ge=0, le=100)
    """A dominant drive stays dominant until it falls below this (default: its threshold)."""
    stimulus_weight: float = Field(default=0.0, ge=0, le=100)
    """alpha: how much a full stimulus adds to the motivation."""
    wellbeing_weight: float = Field(default=1.0, ge=0, le=100)
    """omega: the drive's share in wellbeing."""
    stimuli: tuple[StimulusSource, ...] = ()
    """The sources that excite it; its stimulus is the largest of them."""
    relieved_by: dict[StimulusSource, float] = Field(default_factory=dict)
    """Points per minute a full stimulus takes off the drive (a user engaged calms loneliness)."""
    touch_relief: float = Field(default=0.0, ge=0, le=100)
    """Points each caress takes off the drive at once."""
    behavior: str
    """What the robot does when this drive dominates and nobody interacts."""
    satisfied_by: dict[str, float] = Field(default_factory=dict)
    """Behavior name -> points per minute it takes off the drive while it runs."""
    dormant_during: tuple[str, ...] = ()
    """Behaviors during which it does not grow (asleep, the robot gets neither lonely nor bored)."""
    initial: float = Field(default=20.0, ge=0, le=100)
    """The drive when the daemon starts."""

    _check_behavior = field_validator("behavior")(_known_behavior)

    @field_validator("satisfied_by")
    @classmethod
    def _check_satisfied_by(cls, value: dict[str, float]) -> dict[str, float]:
        for name, per_minute in value.items():
            _known_behavior(name)
            if not 0 <= per_minute <= 100:
                raise ValueError(f"{name}: points per minute must be in [0, 100], got {per_minute}")
        return value

    @field_validator("dormant_during")
    @classmethod
    def _check_dormant(cls, value: tuple[str, ...]) -> tuple[str, ...]:
        for name in value:
            _known_behavior(name)
        return value

    @field_validator("relieved_by")
    @classmethod
    def _check_relieved_by(cls, value: dict[str, float]) -> dict[str, float]:
        for name, per_minute in value.items():
            if not 0 <= per_minute <= 100:
                raise ValueError(f"{name}: points per minute must be in [0, 100], got {per_minute}")
        return value

    @field_validator("satiation")
    @classmethod
    def _satiation_below_threshold(cls, value: float | None, info: ValidationInfo) -> float | None:
        threshold = info.data.get("threshold")
        if value is not None and threshold is not None and value > threshold:
            raise ValueError(f"must not exceed the threshold ({threshold:g})")
        return value

    @property
    def release(self) -> float:
        """The level below which a dominant drive lets go."""
        return self.threshold if self.satiation is None else self.satiation


class StimulusConfig(BaseModel):
    """How raw environment values become stimuli in [0, 1]."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    dark_lux: float = Field(default=300.0, gt=0, le=100_000)
    """Light at or above this is not dark at all; 0 lux is fully dark."""
    quiet_db: float = Field(default=30.0, ge=0, le=150)
    """Noise at or below this is fully quiet."""
    loud_db: float = Field(default=60.0, ge=0, le=150)
    """Noise at or above this is not quiet at all."""
    default_engagement: float = Field(default=0.5, ge=0, le=1)
    """The user stimulus when a user is present but engagement is unknown."""

    @model_validator(mode="after")
    def _ordered(self) -> StimulusConfig:
        if self.loud_db <= self.quiet_db:
            raise ValueError(f"loud_db ({self.loud_db}) must be above quiet_db ({self.quiet_db})")
        return self


DEFAULT_DRIVES: dict[str, dict[str, Any]] = {
    "rest": {
        "rate_per_hour": 4.5,
        "amplitude": 0.9,
        "peak_hour": 2.0,
        "threshold": 60.0,
        "satiation": 15.0,
        "stimulus_weight": 15.0,
        "wellbeing_weight": 1.0,
        "stimuli": ("darkness", "quiet"),
        "behavior": "sleep",
        "satisfied_by": {"sleep": 0.2},
        "initial": 20.0,
    },
    "social": {
        "rate_per_hour": 3.0,
        "amplitude": 0.3,
        "peak_hour": 11.0,
        "threshold": 60.0,
        "satiation": 50.0,
        "stimulus_weight": 20.0,
        "wellbeing_weight": 1.0,
        "stimuli": ("user", "caress"),
        "relieved_by": {"user": 1.0},
        "touch_relief": 2.0,
        "behavior": "presentation",
        "satisfied_by": {"presentation": 4.0, "talk": 1.0},
        "dormant_during": ("sleep",),
        "initial": 20.0,
    },
    "play": {
        "rate_per_hour": 4.0,
        "amplitude": 0.5,
        "peak_hour": 16.0,
        "threshold": 50.0,
        "satiation": 40.0,
        "stimulus_weight": 15.0,
        "wellbeing_weight": 1.0,
        "stimuli": ("music",),
        "behavior": "dance",
        "satisfied_by": {"dance": 1.0, "quiz": 0.3, "bingo": 0.3, "jokes": 0.3, "multimedia": 0.3},
        "dormant_during": ("sleep",),
        "initial": 20.0,
    },
}
"""The shipped drives: fatigue that rises at night, loneliness, boredom."""


class MotivationConfig(BaseModel):
    """The whole model's parameters."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    drives: dict[str, DriveConfig] = Field(
        default_factory=lambda: {
            name: DriveConfig.model_validate(spec) for name, spec in DEFAULT_DRIVES.items()
        }
    )
    hysteresis: float = Field(default=10.0, ge=0, le=100)
    """Another motivation must exceed the dominant one by this much to take over."""
    idle_behavior: str = "wait"
    """What the robot does when no motivation is active."""
    stimuli: StimulusConfig = Field(default_factory=lambda: StimulusConfig())

    _check_idle = field_validator("idle_behavior")(_known_behavior)

    @model_validator(mode="before")
    @classmethod
    def _merge_default_drives(cls, data: Any) -> Any:
        if not isinstance(data, dict) or "drives" not in data:
            return data
        given = data["drives"]
        if not isinstance(given, dict):
            return data
        merged: dict[str, Any] = {name: dict(spec) for name, spec in DEFAULT_DRIVES.items()}
        for name, spec in given.items():
            if isinstance(spec, dict) and name in merged:
                merged[name] = {**merged[name], **spec}
            else:
                merged[name] = spec
        return {**data, "drives": merged}

    @model_validator(mode="after")
    def _some_drive(self) -> MotivationConfig:
        if not self.active_drives:
            raise ValueError("drives: at least one drive must be enabled")
        return self

    @property
    def active_drives(self) -> dict[str, DriveConfig]:
        """The enabled drives, in configuration order."""
        return {name: drive for name, drive in self.drives.items() if drive.enabled}


_BOUNDS = ("greater_than_equal", "greater_than", "less_than_equal", "less_than")
_NOT_A_NUMBER = ("float_type", "float_parsing", "finite_number", "int_type", "int_parsing")


def _field_at(loc: tuple[int | str, ...]) -> FieldInfo | None:
    """The field a validation error points at, following models and dict values."""
    kind: Any = MotivationConfig
    field: FieldInfo | None = None
    parts = list(loc)
    while parts:
        part = parts.pop(0)
        if isinstance(kind, type) and issubclass(kind, BaseModel):
            field = kind.model_fields.get(str(part))
            if field is None:
                return None
            kind = field.annotation
        elif get_origin(kind) is dict:
            kind = get_args(kind)[1]  # ``part`` was the key: go on with the value type
        else:
            return None
    return field


def _range(field: FieldInfo) -> str | None:
    """``[0, 100]``, ``(0, 100000]``, ``[0, 24)``: the bounds declared on a field."""
    low: object = None
    high: object = None
    left, right = "[", "]"
    for rule in field.metadata:
        if isinstance(rule, annotated_types.Ge):
            low = rule.ge
        elif isinstance(rule, annotated_types.Gt):
            low, left = rule.gt, "("
        elif isinstance(rule, annotated_types.Le):
            high = rule.le
        elif isinstance(rule, annotated_types.Lt):
            high, right = rule.lt, ")"
    if not isinstance(low, int | float) or not isinstance(high, int | float):
        return None
    return f"{left}{low:g}, {high:g}{right}"


def _describe(first: ErrorDetails) -> str:
    """One error as ``field: what is allowed (got value)``."""
    loc = tuple(first["loc"])
    where = ".".join(str(part) for part in ("motivation", *loc))
    message = str(first["msg"]).removeprefix("Value error, ")
    field = _field_at(loc)
    allowed = _range(field) if field is not None else None
    if allowed is not None and first["type"] in _BOUNDS:
        message = f"must be in {allowed}"
    elif allowed is not None and first["type"] in _NOT_A_NUMBER:
        message = f"must be a number in {allowed}"
    got = first.get("input")
    hidden = isinstance(got, dict | list) or got is None
    hidden = hidden or (isinstance(got, str) and repr(got) in message)
    return f"{where}: {message}" + ("" if hidden else f" (got {got!r})")


def load_config(data: Any) -> MotivationConfig:
    """Validate a ``[motivation]`` table; raise MotivationConfigError with one line.

    The line names the first wrong field and, for a number, its allowed range:
    ``motivation.drives.rest.threshold: must be in [0, 100] (got 150)``.
    """
    try:
        return MotivationConfig.model_validate(data or {})
    except ValidationError as error:
        errors = error.errors()
        more = len(errors) - 1
        tail = f"; and {more} more" if more else ""
        raise MotivationConfigError(f"{_describe(errors[0])}{tail}") from None
