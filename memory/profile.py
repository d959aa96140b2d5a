"""The profile snapshot the daemon holds, and the rules every profile value obeys.

:class:`Profile` is a frozen copy of one user's row and activity scores (not the
history), safe to share between threads and to keep while the database is down.
:func:`validate_fields` checks the values of an update and names the field that is
wrong; it is the only gate into the ``users`` table.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from datetime import datetime
from typing import Any

from pydantic import BaseModel, ConfigDict

from memory.errors import ProfileError

AttributeValue = str | int | float | bool
"""What a free attribute may hold: the value kinds of DMSL."""

PROACTIVITY_LEVELS = ("low", "moderate", "high", "unknown")
INTERACTION_STYLES = ("voice", "screen")
LIKED_AT = 0.6
"""An activity is in ``params.user.likes`` when the user's own score reaches this."""


@dataclass(frozen=True, slots=True)
class FieldRule:
    """How one profile field is checked and how rules see it (``kind``)."""

    kind: str
    check: Callable[[Any], Any]
    nullable: bool = True


def _text(max_length: int) -> Callable[[Any], str]:
    def check(value: Any) -> str:
        if not isinstance(value, str) or not value.strip():
            raise ValueError("must be a non-empty string")
        text = value.strip()
        if len(text) > max_length:
            raise ValueError(f"must be at most {max_length} characters")
        return text

    return check


def _choice(*choices: str) -> Callable[[Any], str]:
    def check(value: Any) -> str:
        if not isinstance(value, str) or value.strip().lower() not in choices:
            raise ValueError(f"must be one of {', '.join(choices)}")
        return value.strip().lower()

    return check


def _number(low: float, high: float, integer: bool = False) -> Callable[[Any], float | int]:
    def check(value: Any) -> float | int:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ValueError("must be a number")
        if not math.isfinite(value) or not low <= value <= high:
            raise ValueError(f"must be between {low:g} and {high:g}")
        if integer:
            if value != int(value):
                raise ValueError("must be a whole number")
            return int(value)
        return float(value)

    return check


def _boolean(value: Any) -> bool:
    if not isinstance(value, bool):
        raise ValueError("must be true or false")
    return value


FIELDS: dict[str, FieldRule] = {
    "name": FieldRule("string", _text(200)),
    "age": FieldRule("number", _number(0, 130, integer=True)),
    "sex": FieldRule("string", _choice("female", "male", "other")),
    "language": FieldRule("string", _text(50)),
    "hearing": FieldRule("boolean", _boolean),
    "dialogue_mode": FieldRule("string", _choice("guided", "simple", "normal", "advanced")),
    "interaction_style": FieldRule("string", _choice(*INTERACTION_STYLES), nullable=False),
    "volume": FieldRule("number", _number(0, 100)),
    "distance": FieldRule("number", _number(0, 5)),
    "robot_initiative_frequency": FieldRule("string", _choice("low", "moderate", "high")),
    "proactivity": FieldRule("string", _choice(*PROACTIVITY_LEVELS), nullable=False),
    "proactivity_confidence": FieldRule("number", _number(0, 1), nullable=False),
    "bondlevel": FieldRule("number", _number(0, 5, integer=True)),
    "favorite_room": FieldRule("string", _text(100)),
}
"""The profile's fixed fields (columns of ``users``), in ``params.user`` order."""

ALIASES = {"gender": "sex", "favoriteroom": "favorite_room"}
"""Other names a caller may use for a field (the personas say ``gender``; the users of
"Combining Finite State Machine and Decision-Making Tools for Adaptable Robot Behavior"
have a ``favoriteroom``)."""

RESERVED = frozenset({"id", "user_id", "likes", "created_at", "updated_at", "version", "write_id"})
ATTRIBUTE_NAME = re.compile(r"[a-z][a-z0-9_]{0,49}")
"""An attribute name, matched whole (``fullmatch``: with ``$`` a name ending in a line
break would pass)."""
MAX_ATTRIBUTES = 100


def validate_fields(fields: Mapping[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """Split ``fields`` into checked column values and free attributes.

    A value of None clears a nullable field or removes an attribute.

    Raises:
        ProfileError: naming the first field whose name or value is wrong.
    """
    columns: dict[str, Any] = {}
    attributes: dict[str, Any] = {}
    for raw_name, value in fields.items():
        name = ALIASES.get(raw_name, raw_name)
        rule = FIELDS.get(name)
        if rule is not None:
            if value is None:
                if not rule.nullable:
                    raise ProfileError(f"{name}: cannot be cleared")
                columns[name] = None
                continue
            try:
                columns[name] = rule.check(value)
            except ValueError as error:
                raise ProfileError(f"{name}: {error} (got {value!r:.60})") from None
            continue
        if name in RESERVED or not ATTRIBUTE_NAME.fullmatch(name):
            raise ProfileError(
                f"{name!r:.60}: not a profile field name (lower case letters, digits and _, "
                "not id, user_id, likes, version, write_id)"
            )
        if value is not None and (
            not isinstance(value, str | int | float | bool)
            or (isinstance(value, float) and not math.isfinite(value))
            or (isinstance(value, str) and len(value) > 500)
        ):
            raise ProfileError(
                f"{name}: must be a string, number or true/false (got {value!r:.60})"
            )
        attributes[name] = value
    return columns, attributes


class ActivityScore(BaseModel):
    """The user's own evidence about one activity."""

    model_config = ConfigDict(frozen=True, defer_build=True)

    feedback_sum: float = 0.0
    feedback_count: int = 0
    completions: int = 0
    cancellations: int = 0

    @property
    def evidence(self) -> float:
        """How many observations back the score (a cancellation or completion counts 1)."""
        return self.feedback_count + self.completions + self.cancellations

    @property
    def liking_sum(self) -> float:
        """Sum of observed likings in 0..1: feedback as given, a completion 0.7, a
        cancellation 0.1 (a user who stops an activity rarely liked it)."""
        return self.feedback_sum + 0.7 * self.completions + 0.1 * self.cancellations

    def mean(self) -> float | None:
        """The mean observed liking, None without evidence."""
        return self.liking_sum / self.evidence if self.evidence else None


class Profile(BaseModel):
    """A frozen snapshot of one user's profile: every field but the history."""

    model_config = ConfigDict(frozen=True, defer_build=True)

    user_id: str
    created_at: datetime
    updated_at: datetime
    name: str | None = None
    age: int | None = None
    sex: str | None = None
    language: str | None = None
    hearing: bool | None = None
    dialogue_mode: str | None = None
    interaction_style: str = "voice"
    volume: float | None = None
    distance: float | None = None
    robot_initiative_frequency: str | None = None
    proactivity: str = "unknown"
    proactivity_confidence: float = 0.0
    bondlevel: int | None = None
    favorite_room: str | None = None
    attributes: dict[str, AttributeValue] = {}
    scores: dict[str, ActivityScore] = {}
    voice_failures: int = 0
    screen_failures: int = 0
    initiative_taken: int = 0
    initiative_offered: int = 0
    version: int = 0
    """The row's version when read: bumped by every write (several robots, docs/fleet.md)."""

    def likes(self) -> frozenset[str]:
        """Activities whose own score reaches :data:`LIKED_AT`."""
        return frozenset(
            name
            for name, score in self.scores.items()
            if (mean := score.mean()) is not None and mean >= LIKED_AT
        )

    def params(self) -> dict[str, Any]:
        """``params.user.*`` for DMSL rules: set fields, free attributes and ``likes``.

        Unset fields are left out (a rule sees them as unknown); an attribute never
        hides a fixed field.
        """
        out: dict[str, Any] = {
            name: value for name, value in self.attributes.items() if value is not None
        }
        for name in FIELDS:
            value = getattr(self, name)
            if value is not None:
                out[name] = value
        out["likes"] = self.likes()
        return out

    def features(self) -> dict[str, AttributeValue]:
        """What the preference predictor may use: set fields and attributes."""
        found: dict[str, AttributeValue] = {
            name: value for name, value in self.attributes.items() if value is not None
        }
        for name in ("age", "sex", "language", "hearing"):
            value = getattr(self, name)
            if value is not None:
                found[name] = value
        return found

    def missing(self, name: str) -> bool:
        """Whether ``name`` (a field or an attribute) has no value yet."""
        if name in FIELDS:
            return getattr(self, name) is None
        return self.attributes.get(name) is None
