"""Command line of DMSL (``dms rules check|eval|schema``), mounted by dms.cli.

Each command imports the rule language when it runs, so that ``dms rules --help`` is quick.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from dms.kernel.errors import DmsError

if TYPE_CHECKING:
    from dms.rules.schema import ParameterSchema

app = typer.Typer(no_args_is_help=True)

PROFILES = ("user", "robot", "env")


class ParamsError(DmsError, ValueError):
    """A ``--params`` or ``--param`` value that cannot be read."""


def parse_params(params_json: str | None, assignments: list[str]) -> dict[str, dict[str, Any]]:
    """``--params`` JSON merged with ``--param PROFILE.NAME=VALUE`` (which win).

    Raises:
        ParamsError: bad JSON, an unknown profile, or an assignment without ``=``.
    """
    params: dict[str, dict[str, Any]] = {profile: {} for profile in PROFILES}
    if params_json is not None:
        try:
            loaded = json.loads(params_json)
        except json.JSONDecodeError as error:
            raise ParamsError(f"--params is not JSON: {error}") from None
        if not isinstance(loaded, dict):
            raise ParamsError('--params must be an object like {"user": {"age": 80}}')
        for profile, values in loaded.items():
            if profile not in PROFILES:
                raise ParamsError(f"--params: unknown profile {profile!r} (use user, robot or env)")
            if not isinstance(values, dict):
                raise ParamsError(f"--params: {profile} must be an object")
            params[profile].update(values)
    for assignment in assignments:
        target, equals, text = assignment.partition("=")
        profile, dot, name = target.partition(".")
        if not equals or not dot or not name:
            raise ParamsError(f"--param {assignment!r}: write PROFILE.NAME=VALUE")
        if profile not in PROFILES:
            raise ParamsError(f"--param {assignment!r}: unknown profile {profile!r}")
        try:
            value: Any = json.loads(text)
        except json.JSONDecodeError:
            value = text
        params[profile][name] = value
    return params


def stderr_is_terminal() -> bool:
    """Whether caret excerpts go to stderr (a person is watching)."""
    return sys.stderr.isatty()


@app.command()
def check(
    files: Annotated[list[Path], typer.Argument(help="Rules files, checked together.")],
    schema: Annotated[
        Path | None, typer.Option(help="Parameter schema JSON (see `dms rules schema`).")
    ] = None,
) -> None:
    """Verify rules files: exit 0 when valid, else 1 with FILE:LINE:COL: message lines.

    Warnings (``FILE:LINE:COL: warning: ...``) go to stderr and leave the exit code at 0.
    """
    from dms.rules.loader import lint_files
    from dms.rules.schema import ParameterSchema

    loaded = ParameterSchema.load(schema) if schema is not None else None
    problems, warnings = lint_files(files, loaded)
    for warning in warnings:
        typer.echo(str(warning), err=True)
    show_excerpts = stderr_is_terminal()
    for problem in problems:
        typer.echo(str(problem))
        if show_excerpts:
            excerpt = problem.excerpt()
            if excerpt:
                typer.echo(f"{problem}\n{excerpt}", err=True)
    if problems:
        raise typer.Exit(1)


@app.command("eval")
def eval_command(
    file: Annotated[Path, typer.Argument(help="Rules file.")],
    component: Annotated[str, typer.Argument(help="Component to evaluate.")],
    params: Annotated[
        str | None, typer.Option("--params", help='{"user": {...}, "robot": {...}, "env": {...}}')
    ] = None,
    param: Annotated[
        list[str] | None,
        typer.Option("--param", help="PROFILE.NAME=VALUE (a JSON literal, else a string)."),
    ] = None,
) -> None:
    """Evaluate COMPONENT and print {"activate": [...], "cancel": [...], "missing": [...]}."""
    from dms.rules.loader import load_rules

    values = parse_params(params, param or [])
    rules = load_rules([file])
    if not rules.defines(component):
        known = ", ".join(sorted(rules.components)) or "none"
        raise ParamsError(f"{file}: no component {component!r} (components: {known})")
    typer.echo(json.dumps(rules.evaluate(component, values).to_json()))


def daemon_schema() -> ParameterSchema:
    """The parameters the daemon binds: user from the profile model, robot and env as
    docs/contract.md lists them (the behaviors' placeholders read the same list)."""
    from activities.known import ENV_PARAMETERS, ROBOT_PARAMETERS
    from dms.rules.schema import ParameterSchema

    try:
        from memory.parameters import (  # type: ignore[import-not-found,unused-ignore]
            user_parameter_types,
        )
    except ImportError as error:
        raise DmsError(f"cannot list the user parameters: {error}") from None
    return ParameterSchema.model_validate(
        {
            "user": user_parameter_types(),
            "robot": dict(ROBOT_PARAMETERS),
            "env": dict(ENV_PARAMETERS),
        }
    )


@app.command("schema")
def schema_command(
    out: Annotated[Path | None, typer.Option(help="Write here instead of stdout.")] = None,
) -> None:
    """Write the daemon's parameter schema JSON (for `dms rules check --schema`)."""
    text = daemon_schema().dump()
    if out is None:
        typer.echo(text, nl=False)
    else:
        out.write_text(text, encoding="utf-8")
        typer.echo(str(out))
