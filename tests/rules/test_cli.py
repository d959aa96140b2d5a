"""`dms rules check|eval|schema` as the contract says, driven through the rules typer app."""

from __future__ import annotations

import json
import sys
import types
from collections.abc import Callable
from pathlib import Path

import pytest
from typer.testing import CliRunner, Result

from dms import rules_cli
from dms.kernel.errors import DmsError

from .conftest import EXAMPLES

Write = Callable[..., Path]
OBSTACLE = str(EXAMPLES / "obstacle.dmsl")


def dms_rules(*args: str) -> Result:
    return CliRunner().invoke(rules_cli.app, list(args))


def test_check_valid_files_exits_0() -> None:
    result = dms_rules("check", OBSTACLE, str(EXAMPLES / "decisions.dmsl"))
    assert result.exit_code == 0
    assert result.stdout == ""


def test_check_prints_one_line_per_problem_and_exits_1(write: Write) -> None:
    bad = write('component C [ if x then activate "a" ]\ncomponent C [ activate "b" ]\n')
    result = dms_rules("check", OBSTACLE, str(bad), "missing.dmsl")
    assert result.exit_code == 1
    assert result.stdout.splitlines() == [
        "missing.dmsl:1:1: cannot read: No such file or directory",
        f"{bad}:1:18: unknown name 'x'",
        f"{bad}:2:1: duplicate component 'C' (first at {bad}:1:1)",
    ]
    assert result.stderr == ""  # not a terminal: no excerpts


def test_check_shows_caret_excerpts_on_a_terminal(
    write: Write, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(rules_cli, "stderr_is_terminal", lambda: True)
    bad = write('component C [\n  if params.user.a > "x" then activate "a"\n]\n')
    result = dms_rules("check", str(bad))
    assert result.exit_code == 1
    line = f"{bad}:2:22: type error: '>' needs numbers, got a string"
    assert result.stdout.splitlines() == [line]
    assert result.stderr.splitlines() == [
        line,
        '  if params.user.a > "x" then activate "a"',
        "                     ^",
    ]


def test_check_with_schema_catches_a_misspelled_parameter(tmp_path: Path) -> None:
    schema = tmp_path / "schema.json"
    schema.write_text(
        json.dumps(
            {
                "user": {"hearing": "boolean", "age": "number", "bondlevel": "number"},
                "robot": {"batterylevel": "number", "currentroom": "string"},
                "env": {"time": "number", "currentbestpath": "boolean"},
            }
        ),
        encoding="utf-8",
    )
    result = dms_rules("check", OBSTACLE, "--schema", str(schema))
    assert result.exit_code == 1
    assert result.stdout.splitlines() == [
        f"{OBSTACLE}:15:36: unknown parameter params.user.favoriteroom"
    ]


def test_check_with_a_bad_schema_is_one_error(tmp_path: Path) -> None:
    schema = tmp_path / "schema.json"
    schema.write_text("[]", encoding="utf-8")
    result = dms_rules("check", OBSTACLE, "--schema", str(schema))
    assert result.exit_code != 0
    assert isinstance(result.exception, DmsError)
    assert "invalid schema" in str(result.exception)


def test_eval_prints_the_result_object() -> None:
    result = dms_rules(
        "eval",
        OBSTACLE,
        "ObstacleDetected",
        "--params",
        '{"user": {"hearing": true, "age": 70, "bondlevel": 4}, "env": {"time": 11}}',
        "--param",
        "robot.batterylevel=5",
    )
    assert result.exit_code == 0, result.output
    assert json.loads(result.stdout) == {"activate": ["help"], "cancel": [], "missing": []}


def test_eval_param_values_are_json_literals_else_strings() -> None:
    result = dms_rules(
        "eval",
        OBSTACLE,
        "ObstacleDetected",
        "--param",
        "user.hearing=true",
        "--param",
        "user.age=70",
        "--param",
        "user.bondlevel=4",
        "--param",
        "env.time=12",
        "--param",
        "env.currentbestpath=true",
        "--param",
        "robot.batterylevel=50",
        "--param",
        "robot.currentroom=kitchen",
        "--param",
        "user.favoriteroom=kitchen",
    )
    assert result.exit_code == 0, result.output
    assert json.loads(result.stdout) == {"activate": ["help"], "cancel": [], "missing": []}


def test_param_overrides_params_and_missing_is_reported() -> None:
    result = dms_rules(
        "eval",
        OBSTACLE,
        "ObstacleDetected",
        "--params",
        '{"user": {"age": 50}}',
        "--param",
        "user.age=85",
    )
    assert json.loads(result.stdout) == {
        "activate": ["plan"],
        "cancel": [],
        "missing": ["user.hearing"],
    }


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--params", "{not json"], "--params is not JSON"),
        (["--params", "[1]"], "--params must be an object"),
        (["--params", '{"users": {}}'], "unknown profile 'users'"),
        (["--params", '{"user": 3}'], "--params: user must be an object"),
        (["--param", "user.age"], "write PROFILE.NAME=VALUE"),
        (["--param", "age=3"], "write PROFILE.NAME=VALUE"),
        (["--param", "person.age=3"], "unknown profile 'person'"),
    ],
)
def test_eval_bad_parameters_are_one_line_errors(args: list[str], message: str) -> None:
    result = dms_rules("eval", OBSTACLE, "ObstacleDetected", *args)
    assert result.exit_code != 0
    assert isinstance(result.exception, DmsError)
    assert message in str(result.exception)
    assert "\n" not in str(result.exception)


def test_eval_of_invalid_rules_or_unknown_component(write: Write) -> None:
    result = dms_rules("eval", str(write("def x (")), "C")
    assert isinstance(result.exception, DmsError)
    assert "syntax error" in str(result.exception)
    result = dms_rules("eval", OBSTACLE, "Nope")
    assert isinstance(result.exception, DmsError)
    assert "no component 'Nope' (components: ObstacleDetected)" in str(result.exception)


@pytest.fixture
def user_parameters(monkeypatch: pytest.MonkeyPatch) -> None:
    """Stands in for memory.parameters (the profile model), which owns the user names."""
    module = types.ModuleType("memory.parameters")
    module.user_parameter_types = lambda: {  # type: ignore[attr-defined]
        "age": "number",
        "hearing": "boolean",
        "bondlevel": "number",
        "favoriteroom": "string",
    }
    monkeypatch.setitem(sys.modules, "memory.parameters", module)


@pytest.mark.usefixtures("user_parameters")
def test_schema_writes_the_daemon_schema_and_check_uses_it(tmp_path: Path) -> None:
    out = tmp_path / "schema.json"
    result = dms_rules("schema", "--out", str(out))
    assert result.exit_code == 0, result.output
    written = json.loads(out.read_text(encoding="utf-8"))
    assert written["user"]["age"] == "number"
    assert written["robot"]["batterylevel"] == "number"
    assert written["robot"]["name"] == "string"
    assert written["env"] == {
        "time": "number",
        "noise_db": "number",
        "light_lux": "number",
        "currentbestpath": "boolean",
    }
    assert json.loads(dms_rules("schema").stdout) == written
    assert dms_rules("check", OBSTACLE, "--schema", str(out)).exit_code == 0
    typo = tmp_path / "typo.dmsl"
    typo.write_text('component C [ if params.user.agee > 3 then activate "a" ]\n', encoding="utf-8")
    result = dms_rules("check", str(typo), "--schema", str(out))
    assert result.exit_code == 1
    assert (
        result.stdout == f"{typo}:1:18: unknown parameter params.user.agee; did you mean 'age'?\n"
    )
