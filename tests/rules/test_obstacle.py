"""The DMSL paper's ObstacleDetected rule (section 4) behaves as the paper says."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from dms.rules import check_files, check_outcomes, load_rules, parse

from .conftest import EXAMPLES

OBSTACLE = EXAMPLES / "obstacle.dmsl"

# A user who may be disturbed and a robot with no reason to ask for help.
CALM: dict[str, dict[str, Any]] = {
    "user": {"hearing": True, "age": 70, "bondlevel": 4, "favoriteroom": "kitchen"},
    "robot": {"batterylevel": 80, "currentroom": "hall"},
    "env": {"time": 11, "currentbestpath": True},
}


def with_(**changes: Any) -> dict[str, dict[str, Any]]:
    """CALM with ``profile__name=value`` changes (value None removes the parameter)."""
    params = {profile: dict(values) for profile, values in CALM.items()}
    for key, value in changes.items():
        profile, name = key.split("__")
        if value is None:
            params[profile].pop(name, None)
        else:
            params[profile][name] = value
    return params


@pytest.mark.parametrize(
    ("params", "activate", "missing"),
    [
        # nothing says "plan" and nothing says "help": no decision, the state's default
        (CALM, (), ()),
        # the five reasons not to disturb the user
        (with_(user__hearing=False), ("plan",), ()),
        (with_(user__age=81), ("plan",), ()),
        (with_(user__age=80), (), ()),
        (with_(user__age=80.5), ("plan",), ()),
        (with_(user__bondlevel=1), ("plan",), ()),
        (with_(user__bondlevel=3), (), ()),
        (with_(env__time=14), ("plan",), ()),
        (with_(env__time=21), (), ()),
        (with_(env__time=9), ("plan",), ()),
        # the reasons to call the user for help
        (with_(robot__batterylevel=9), ("help",), ()),
        (with_(robot__batterylevel=10), (), ()),
        (with_(env__currentbestpath=False), ("help",), ()),
        (with_(robot__currentroom="kitchen"), ("help",), ()),
        # not disturbing wins over asking for help
        (with_(user__age=90, robot__batterylevel=5), ("plan",), ()),
        # missing parameters are unknown, and the result names them
        (with_(user__hearing=None), (), ("user.hearing",)),
        (with_(user__hearing=None, user__age=85), ("plan",), ("user.hearing",)),
        (with_(user__hearing=None, robot__batterylevel=5), ("help",), ("user.hearing",)),
        (with_(env__time=None, robot__batterylevel=5), ("help",), ("env.time",)),
        (with_(robot__currentroom=None), (), ("robot.currentroom",)),
        (
            {},
            (),
            (
                "env.currentbestpath",
                "env.time",
                "robot.batterylevel",
                "robot.currentroom",
                "user.age",
                "user.bondlevel",
                "user.favoriteroom",
                "user.hearing",
            ),
        ),
    ],
)
def test_obstacle_rule_decides_plan_or_help(
    params: dict[str, dict[str, Any]], activate: tuple[str, ...], missing: tuple[str, ...]
) -> None:
    result = load_rules([OBSTACLE]).evaluate("ObstacleDetected", params)
    assert result.activate == activate
    assert result.cancel == ()
    assert result.missing == missing


def test_the_paper_text_parses_as_written() -> None:
    program = parse(OBSTACLE.read_text(encoding="utf-8"), str(OBSTACLE))
    assert [d.name for d in program.definitions] == [
        "neutralToBond",
        "willingToBond",
        "userFreeTimes",
    ]
    assert [c.name for c in program.components] == ["ObstacleDetected"]
    assert check_files([OBSTACLE]) == []


def test_outcomes_are_the_transitions_of_the_obstructed_state() -> None:
    rules = load_rules([OBSTACLE])
    assert check_outcomes(rules, "ObstacleDetected", {"plan", "help"}) == []
    problems = check_outcomes(rules, "ObstacleDetected", {"plan", "wait"})
    assert [str(p) for p in problems] == [
        f'{OBSTACLE}:17:9: activation "help" of ObstacleDetected is not an outcome '
        'of the state (outcomes: "plan", "wait")'
    ]


def test_examples_all_verify() -> None:
    files = sorted(Path(EXAMPLES).glob("*.dmsl"))
    assert len(files) >= 2
    assert check_files(files) == []
    rules = load_rules(files)
    assert {"ObstacleDetected", "ChooseMode", "ChooseEntertainment"} <= rules.components
    assert {"AllowInterruption", "VoiceSettings"} <= rules.components
