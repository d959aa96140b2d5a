"""Warnings of the verifier: components that may activate nothing on some path.

The verifier reports "components that may activate nothing"; the DMSL paper's
``ObstacleDetected`` does so on purpose, so it is a warning (stderr, exit 0), not an error.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest
from typer.testing import CliRunner

from dms import rules_cli
from dms.rules import lint_files, parse
from dms.rules.verifier import activation_warnings

from .conftest import EXAMPLES

Write = Callable[..., Path]


def _warned(text: str) -> list[str]:
    return [f"{p.line}:{p.column}: {p.message}" for p in activation_warnings([parse(text, "r")])]


def _names(text: str) -> list[str]:
    return [line.split("'")[1] for line in _warned(text)]


@pytest.mark.parametrize(
    "text",
    [
        'component C [ activate "a" ]',
        'component C [ if params.user.x then activate "a" else activate "b" ]',
        'component C [ if params.user.x then [ cancel "z" activate "a" ] else activate "b" ]',
        'component C [ if params.user.x then cancel "z" activate "a" ]',
        'component B [ activate "b" ]\ncomponent C [ evaluate B ]',
        'component C [ if params.user.x then activate "a" else if params.user.y then '
        'activate "b" else activate "c" ]',
    ],
)
def test_components_that_always_activate_are_not_warned(text: str) -> None:
    assert _warned(text) == []


def test_an_if_without_else_is_the_spot() -> None:
    text = 'component C [\n    if params.user.x then activate "a"\n]'
    assert _warned(text) == [
        "2:5: warning: component 'C' may activate nothing on a path through here "
        "(the caller's built-in logic decides then)"
    ]


def test_nested_paths_and_evaluate_are_followed() -> None:
    inner = (
        'component C [ if params.user.x then [ if params.user.y then activate "a" ] '
        'else activate "b" ]'
    )
    assert _names(inner) == ["C"]
    via = 'component B [ if params.user.x then activate "b" ]\ncomponent C [ evaluate B ]'
    assert _names(via) == ["B", "C"]
    assert _names('component C [ cancel "a" ]') == ["C"]


def test_examples_warn_only_where_the_seed_intends() -> None:
    problems, warnings = lint_files([EXAMPLES / "obstacle.dmsl", EXAMPLES / "decisions.dmsl"])
    assert problems == []
    assert [w.message.split("'")[1] for w in warnings] == ["ObstacleDetected"]


def test_no_warnings_while_there_are_problems(write: Write) -> None:
    path = write('component C [ if nope then activate "a" ]')
    problems, warnings = lint_files([path])
    assert [p.message for p in problems] == ["unknown name 'nope'"] and warnings == []


def test_rules_check_prints_warnings_on_stderr_and_exits_0(write: Write) -> None:
    path = write('component C [\n    if params.user.x then activate "a"\n]')
    result = CliRunner().invoke(rules_cli.app, ["check", str(path)])
    assert result.exit_code == 0
    assert result.stdout == ""
    assert result.stderr.splitlines() == [
        f"{path}:2:5: warning: component 'C' may activate nothing on a path through here "
        "(the caller's built-in logic decides then)"
    ]
