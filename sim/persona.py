"""Personas: who a simulated user is, what they secretly like, how they behave.

A persona is a YAML file under ``sim/personas/`` (or any path). Its fields:

- ``features``: what the user would tell the robot when asked (age, gender, ...);
- ``preferences``: the hidden true liking, 0..1, of each of the 8 entertainment
  activities (missing ones are 0.5): used to tap menus, rate activities and lose patience;
- ``proactivity``: ``low``, ``moderate`` or ``high`` (how often they take the initiative:
  a low one mostly leaves the menu's choice to the robot, "you choose");
- ``speech``: recognition error rate, answer delays, chance of not answering, and
  whether they rather answer by voice or on the screen;
- ``patience``: in an activity they like less than ``dislike_below`` they touch the
  right shoulder after ``stop_after_s`` and say "stop"; up to ``bored_below`` they may
  still do so, the less often the better they like it;
- ``visits``: when they come to the robot (days, time of day, minutes).
"""

from __future__ import annotations

from datetime import time
from pathlib import Path
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from dms.kernel.activity_names import ENTERTAINMENT_ACTIVITIES
from sim.errors import SpecError
from sim.specfile import load_spec

PERSONA_DIR = Path(__file__).parent / "personas"
Probability = Annotated[float, Field(ge=0.0, le=1.0)]
Proactivity = Literal["low", "moderate", "high"]
Weekday = Literal["mon", "tue", "wed", "thu", "fri", "sat", "sun"]
WEEKDAYS: tuple[Weekday, ...] = ("mon", "tue", "wed", "thu", "fri", "sat", "sun")
FeatureValue = str | int | float | bool
DECLINE_MENU_RATE: dict[str, float] = {"low": 0.8, "moderate": 0.4, "high": 0.0}
"""By proactivity, the chance of leaving a menu's choice to the robot: what makes a
persona's proactivity its true one (a low one lets the robot lead). A moderate one is by
definition between the two: half way between the low and the high one's rates (one that
never declines would take the initiative as often as a high one)."""
INITIATIVE_ANSWER: dict[str, str] = {"low": "high", "moderate": "moderate", "high": "low"}
"""By proactivity, the answer to "how often should I start a conversation?": a user who
lets the robot lead wants it to start often."""


class _Spec(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Span(_Spec):
    """A range of seconds; a value is drawn uniformly in it."""

    min: float = Field(ge=0.0)
    max: float = Field(ge=0.0)

    @model_validator(mode="before")
    @classmethod
    def _from_list(cls, value: object) -> object:
        if isinstance(value, list | tuple) and len(value) == 2:
            return {"min": value[0], "max": value[1]}
        if isinstance(value, int | float) and not isinstance(value, bool):
            return {"min": value, "max": value}
        return value

    @model_validator(mode="after")
    def _ordered(self) -> Span:
        if self.max < self.min:
            raise ValueError(f"max {self.max} is below min {self.min}")
        return self


class SpeechHabits(_Spec):
    """How the user answers."""

    error_rate: Probability = 0.05
    """Chance that an utterance is misrecognized (it arrives garbled)."""
    answer_delay_s: Span = Span(min=1.5, max=4.0)
    no_answer_rate: Probability = 0.02
    """Chance of not answering a question at all."""
    screen_rate: Probability = 0.5
    """Chance of answering on the touch screen when choices are shown."""
    menu_delay_s: Span | None = None
    """Time to look through a menu of activities and pick one (None: ``answer_delay_s``).
    The paper's participants browsed touch-screen menus they had never seen."""
    rating_delay_s: Span | None = None
    """Time to rate an activity from 1 to 5 (None: ``answer_delay_s``)."""


class Patience(_Spec):
    """When the user stops an activity they do not like."""

    dislike_below: Probability = 0.35
    bored_below: Probability | None = None
    """Between ``dislike_below`` and this liking the user may still stop the activity,
    the less likely the better they like it (None: only below ``dislike_below``)."""
    stop_after_s: Span = Span(min=20.0, max=60.0)
    continue_rate: Probability = 0.1
    """Chance of answering "continue" after all when the robot asks."""
    max_touches: int | None = Field(default=None, ge=0)
    """At most this many shoulder touches while present (None: no limit)."""


class Visit(_Spec):
    """One recurring visit: on these days, around this time, for about this long."""

    days: list[Weekday] | Literal["daily"] = "daily"
    at: time
    minutes: float = Field(gt=0.0, le=24 * 60)
    jitter_min: float = Field(10.0, ge=0.0, le=180.0)

    @field_validator("at", mode="before")
    @classmethod
    def _clock_time(cls, value: object) -> object:
        if isinstance(value, int) and not isinstance(value, bool):
            # YAML 1.1 reads 10:30 as a sexagesimal number (630); take it back.
            return time(value // 60, value % 60) if 0 <= value < 24 * 60 else value
        return value

    def weekdays(self) -> tuple[Weekday, ...]:
        return WEEKDAYS if self.days == "daily" else tuple(self.days)


class Preferences(_Spec):
    """Hidden true liking, 0..1, of each entertainment activity (0.5 when not given);
    ``declared`` holds those of declared activities, by name."""

    multimedia: Probability = 0.5
    news: Probability = 0.5
    weather: Probability = 0.5
    quiz: Probability = 0.5
    dance: Probability = 0.5
    bingo: Probability = 0.5
    jokes: Probability = 0.5
    sayings: Probability = 0.5
    declared: dict[Annotated[str, Field(pattern=r"^[a-z][a-z0-9_]{0,39}$")], Probability] = Field(
        default_factory=dict, max_length=64
    )
    """Liking of declared activities (a behavior folder's), by name."""


class Persona(_Spec):
    """One simulated user."""

    name: Annotated[str, Field(pattern=r"^[a-z0-9_-]{1,64}$")]
    description: str = ""
    user_id: Annotated[str, Field(pattern=r"^[a-z0-9_-]{1,64}$")] | None = None
    features: dict[str, FeatureValue] = Field(default_factory=dict)
    preferences: Preferences = Preferences()
    proactivity: Proactivity = "moderate"
    ask_by_name_rate: Probability = 0.2
    """Chance, when the robot is free, of asking for a favourite activity by name."""
    answers: dict[str, str] = Field(default_factory=dict)
    """Set answers: a question containing the key (any case) is answered with the value,
    e.g. ``{"how often should i start": "high"}``."""
    decline_menu_rate: Probability | None = None
    """Chance of leaving a menu's choice to the robot ("you choose"); None: by
    proactivity (:data:`DECLINE_MENU_RATE`)."""
    speech: SpeechHabits = SpeechHabits()
    patience: Patience = Patience()
    arrive_after_s: Span = Span(min=1.0, max=3.0)
    """After being placed in front of the robot, how long until ready to interact."""
    visits: list[Visit] = Field(default_factory=list)

    @property
    def id(self) -> str:
        return self.user_id or self.name

    def stop_chance(self, activity: str) -> float:
        """The chance that this user stops ``activity`` before its end: 1 below
        ``dislike_below``, falling to 0 at ``bored_below``."""
        liking, patience = self.liking(activity), self.patience
        if liking < patience.dislike_below:
            return 1.0
        top = patience.bored_below
        if top is None or liking >= top or top <= patience.dislike_below:
            return 0.0
        return (top - liking) / (top - patience.dislike_below)

    def liking(self, activity: str) -> float:
        """The hidden true preference for ``activity`` (0.5 when not stated)."""
        value = (
            self.preferences.declared.get(activity)
            if activity in self.preferences.declared
            else getattr(self.preferences, activity, None)
            if activity in ENTERTAINMENT_ACTIVITIES
            else None
        )
        return float(value) if value is not None else 0.5

    def declines_menu(self) -> float:
        """The chance that this user leaves the menu's choice to the robot."""
        if self.decline_menu_rate is not None:
            return self.decline_menu_rate
        return DECLINE_MENU_RATE[self.proactivity]

    def initiative_answer(self) -> str:
        """The answer to the general question on initiative that the persona's
        proactivity gives (an ``answers`` entry naming the question wins over it)."""
        return INITIATIVE_ANSWER[self.proactivity]

    def favourites(self) -> list[str]:
        """Entertainment activities, best liked first."""
        return sorted(ENTERTAINMENT_ACTIVITIES, key=lambda name: -self.liking(name))


def persona_path(name_or_path: str) -> Path:
    """A shipped persona by name (``demo``) or a path to a YAML file."""
    if name_or_path.endswith((".yaml", ".yml")) or "/" in name_or_path:
        return Path(name_or_path)
    path = PERSONA_DIR / f"{name_or_path}.yaml"
    if not path.exists():
        known = ", ".join(shipped_personas())
        raise SpecError(f"unknown persona {name_or_path!r} (shipped: {known})")
    return path


def load_persona(name_or_path: str | Path) -> Persona:
    """Load and validate a persona; SpecError names file, line and field."""
    path = name_or_path if isinstance(name_or_path, Path) else persona_path(name_or_path)
    return load_spec(Persona, path)


def shipped_personas() -> list[str]:
    """Names of the personas that ship with the project."""
    return sorted(path.stem for path in PERSONA_DIR.glob("*.yaml"))
