"""A behavior declared an activity: the ``activity:`` key of a behavior file.

A designer turns a behavior into an activity without code: its manager, its menu name
and picture, how long it usually lasts, the user features that suggest someone likes
it (the preference model's first guess), and whether it may be paused::

    activity:
      manager: entertainment      # entertainment, cognitive, social or relax
      menu: Greet and ask         # the name on the menu
      picture: greet.png          # optional, shown beside it
      expected_s: 240             # optional, seconds
      features: {hobbies: [music, films], age: [70, 100]}
      pausable: true

The loader checks each declaration (:func:`declaration_problems`, one line per problem
saying what to do) and builds the catalogue in force from the shipped activities and
the declared ones (:func:`catalogue_of`); :func:`install_catalogue` puts it in force.
"""

from __future__ import annotations

from collections.abc import Mapping
from difflib import get_close_matches
from typing import Any

from dms.kernel.activity_names import (
    DECLARABLE_MANAGERS,
    MAX_DECLARED,
    NAME_PATTERN,
    SHIPPED,
    TWIN_CUTOFF,
    ActivityEntry,
    Catalogue,
    ManagerName,
    install,
)
from memory.seed_data import EDUCATION, FEATURE_COLUMNS, HOBBIES, OCCUPATIONS

DECLARATION_KEYS = ("manager", "menu", "picture", "expected_s", "features", "pausable")
MAX_EXPECTED_S = 4 * 3600.0
MAX_MENU_CHARS = 40
MAX_VALUES = 16
"""Values one feature may list."""

KNOWN_VALUES: Mapping[str, tuple[str, ...]] = {
    "sex": ("female", "male"),
    "education": EDUCATION,
    "occupation": (*OCCUPATIONS, "student"),
    "hobbies": HOBBIES,
}
"""The values the preference model learnt from, per text feature."""


def declaration_schema() -> dict[str, Any]:
    """The JSON Schema of ``activity:`` (the published behavior schema's, the studio's
    Activity form's): what :func:`declaration_problems` accepts, but the name's checks."""
    values = {"type": "array", "minItems": 1, "maxItems": MAX_VALUES}
    features: dict[str, Any] = {
        name: {**values, "items": {"enum": list(known)}} for name, known in KNOWN_VALUES.items()
    }
    features["age"] = {
        "type": "array",
        "items": {"type": "integer", "minimum": 0, "maximum": 120},
        "minItems": 2,
        "maxItems": 2,
        "description": "[youngest, oldest], whole years.",
    }
    features["lives_alone"] = {**values, "items": {"type": "boolean"}}
    return {
        "type": "object",
        "description": "Declares the behavior an activity: the robot offers it in menus, "
        "starts it on request and chooses it by itself.",
        "properties": {
            "manager": {
                "enum": [m.value for m in DECLARABLE_MANAGERS],
                "description": "The group it runs in; an entertainment activity is chosen "
                "for a user by her preferences.",
            },
            "menu": {
                "type": "string",
                "minLength": 1,
                "maxLength": MAX_MENU_CHARS,
                "description": "The name shown on the menu.",
            },
            "picture": {
                "type": "string",
                "minLength": 1,
                "description": "An image file shown beside it on the menu.",
            },
            "expected_s": {
                "type": "number",
                "exclusiveMinimum": 0,
                "maximum": MAX_EXPECTED_S,
                "description": "How long it usually lasts, in seconds.",
            },
            "features": {
                "type": "object",
                "properties": features,
                "additionalProperties": False,
                "description": "The user features that suggest someone likes it: the "
                "preference model's first guess.",
            },
            "pausable": {
                "type": "boolean",
                "default": True,
                "description": "false: a pause (a reminder, the shoulder, a request) stops "
                "it instead.",
            },
        },
        "required": ["manager", "menu"],
        "additionalProperties": False,
    }


def _manager_problem(raw: object) -> str | None:
    names = ", ".join(m.value for m in DECLARABLE_MANAGERS)
    if isinstance(raw, str) and raw in {m.value for m in DECLARABLE_MANAGERS}:
        return None
    return f"manager {raw!r} is not one of {names}: write one of them"


def _feature_problems(name: str, values: object) -> list[str]:
    if name not in FEATURE_COLUMNS:
        close = get_close_matches(name, FEATURE_COLUMNS, n=1)
        hint = f"did you mean {close[0]}? " if close else ""
        return [
            f"feature {name!r} is not one the preference model learns from: {hint}"
            f"use one of {', '.join(FEATURE_COLUMNS)}"
        ]
    if not isinstance(values, list) or not values or len(values) > MAX_VALUES:
        return [f"feature {name}: write a list of 1 to {MAX_VALUES} values"]
    if name == "age":
        if (
            len(values) != 2
            or not all(isinstance(v, int) and not isinstance(v, bool) for v in values)
            or not 0 <= values[0] <= values[1] <= 120
        ):
            return ["feature age: write [youngest, oldest], whole years, as [70, 100]"]
        return []
    if name == "lives_alone":
        if not all(isinstance(v, bool) for v in values):
            return ["feature lives_alone: write [true] or [false]"]
        return []
    problems = []
    known = KNOWN_VALUES[name]
    for value in values:
        if not isinstance(value, str) or value.strip().lower() not in known:
            problems.append(f"feature {name}: {value!r} is not one of {', '.join(known)}")
    return problems


def declaration_problems(behavior: str, raw: object) -> list[tuple[str | None, str]]:
    """What is wrong with the ``activity:`` of behavior ``behavior``: ``(key, message)``
    pairs, each message saying what to do (key None: the declaration as a whole)."""
    if not isinstance(raw, Mapping):
        return [(None, "activity: write a mapping with at least manager and menu")]
    found: list[tuple[str | None, str]] = []
    if behavior in SHIPPED:
        found.append(
            (
                None,
                f"activity: {behavior!r} is a shipped activity: rename the behavior to "
                "declare a new one (a behavior named for a shipped activity replaces its "
                "steps and needs no declaration)",
            )
        )
    elif not NAME_PATTERN.match(behavior):
        found.append((None, f"activity: {behavior!r} cannot name an activity: use a-z, 0-9 and _"))
    elif twin := get_close_matches(behavior, SHIPPED, n=1, cutoff=TWIN_CUTOFF):
        found.append(
            (
                None,
                f"activity: {behavior!r} is too like the shipped {twin[0]!r} (a typo of "
                "one would start the other): rename the behavior",
            )
        )
    for key in raw:
        if key not in DECLARATION_KEYS:
            close = get_close_matches(str(key), DECLARATION_KEYS, n=1)
            hint = f"did you mean {close[0]}? " if close else ""
            found.append(
                (
                    key,
                    f"activity: unknown key {key!r}: {hint}"
                    f"write one of {', '.join(DECLARATION_KEYS)}",
                )
            )
    if (problem := _manager_problem(raw.get("manager"))) is not None:
        found.append(("manager", f"activity: {problem}"))
    menu = raw.get("menu")
    if not isinstance(menu, str) or not menu.strip() or len(menu) > MAX_MENU_CHARS:
        found.append(
            (
                "menu",
                f"activity: menu: write the name shown on the menu, "
                f"1 to {MAX_MENU_CHARS} characters",
            )
        )
    picture = raw.get("picture")
    if picture is not None and (not isinstance(picture, str) or not picture.strip()):
        found.append(("picture", "activity: picture: write an image file's name"))
    expected = raw.get("expected_s")
    if expected is not None and (
        isinstance(expected, bool)
        or not isinstance(expected, int | float)
        or not 0 < expected <= MAX_EXPECTED_S
    ):
        found.append(
            (
                "expected_s",
                f"activity: expected_s: write seconds, over 0 and at most {MAX_EXPECTED_S:g}",
            )
        )
    features = raw.get("features", {})
    if not isinstance(features, Mapping):
        found.append(("features", "activity: features: write a mapping, as {hobbies: [music]}"))
    else:
        for name, values in features.items():
            found.extend(("features", f"activity: {p}") for p in _feature_problems(name, values))
    if not isinstance(raw.get("pausable", True), bool):
        found.append(("pausable", "activity: pausable: write true or false"))
    return found


def entry_of(behavior: str, raw: Mapping[str, Any]) -> ActivityEntry:
    """The catalogue entry of a declaration :func:`declaration_problems` found right."""
    features = {
        str(name): tuple(v.strip().lower() if isinstance(v, str) else v for v in values)
        for name, values in (raw.get("features") or {}).items()
    }
    expected = raw.get("expected_s")
    return ActivityEntry(
        name=behavior,
        manager=ManagerName(raw["manager"]),
        label=str(raw["menu"]).strip(),
        picture=raw.get("picture"),
        expected_s=float(expected) if expected is not None else None,
        features=features,
        pausable=bool(raw.get("pausable", True)),
    )


def count_problem(declared: int) -> str | None:
    """The problem of a folder that declares more activities than the catalogue holds."""
    if declared <= MAX_DECLARED:
        return None
    return (
        f"{declared} behaviors declare an activity, more than {MAX_DECLARED}: remove the "
        "activity key of those the robot no longer offers"
    )


def catalogue_of(declarations: Mapping[str, Mapping[str, Any]]) -> Catalogue:
    """The shipped activities plus ``declarations`` (behavior name: its checked
    ``activity:``)."""
    return Catalogue([entry_of(name, raw) for name, raw in sorted(declarations.items())])


def install_catalogue(declarations: Mapping[str, Mapping[str, Any]]) -> Catalogue:
    """Put in force the catalogue of ``declarations`` (at start and after a reload)."""
    catalogue = catalogue_of(declarations)
    install(catalogue)
    return catalogue
