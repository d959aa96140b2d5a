"""``dms behavior``: check, draw, step through and run behavior files; print the schema."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from collections.abc import Callable
from enum import StrEnum
from functools import partial
from pathlib import Path
from typing import Annotated

import typer

from activities.diagram import to_dot, to_mermaid
from activities.errors import BehaviorError
from activities.library import BehaviorLibrary, decision_problems
from activities.spec import schema_text
from activities.stepper import BehaviorRun, Step, parse_input
from dms.kernel.ports import RobotPort

app = typer.Typer(no_args_is_help=True)

SKIP = "skip"
"""What ``step`` takes at a question to let it time out."""


class DiagramFormat(StrEnum):
    DOT = "dot"
    MERMAID = "mermaid"
    SVG = "svg"
    PNG = "png"


def _render(dot_text: str, fmt: DiagramFormat) -> bytes:
    """SVG or PNG from Graphviz's ``dot`` (a one-line error where it is not installed)."""
    dot = shutil.which("dot")
    if dot is None:
        typer.echo(
            f"dms: --format {fmt.value} needs Graphviz's dot on PATH (apt-get install "
            "graphviz); --format dot or mermaid need nothing",
            err=True,
        )
        raise typer.Exit(1)
    done = subprocess.run(
        [dot, f"-T{fmt.value}"], input=dot_text.encode(), capture_output=True, timeout=60
    )
    if done.returncode != 0:
        reason = " ".join(done.stderr.decode(errors="replace").split()) or "no reason given"
        typer.echo(f"dms: dot -T{fmt.value} failed: {reason}", err=True)
        raise typer.Exit(1)
    return done.stdout


def _user(user_id: str | None) -> dict[str, object]:
    if user_id is None:
        return {}
    return {"id": user_id, "name": user_id.replace("_", " ").title()}


def _print(step: Step) -> None:
    for line in step.lines():
        typer.echo(line)


@app.command()
def check(
    files: Annotated[list[Path], typer.Argument(help="Behavior files to check.")],
    rules: Annotated[
        list[Path] | None,
        typer.Option(help="Rules files: decide states must declare every activation."),
    ] = None,
) -> None:
    """Check behavior files; one FILE:LINE: state PATH: message line per problem.

    With ``--rules``, a decide state whose DMSL component may activate something that is
    not among its outcomes is a problem too (the rules' own problems first, if any).
    """
    from dms.rules import RulesError, check_outcomes, load_rules

    ruleset = None
    if rules:
        try:
            ruleset = load_rules(rules)
        except RulesError as error:
            for rule_problem in error.problems:
                typer.echo(str(rule_problem))
            raise typer.Exit(1) from None
    failed = False
    for path in files:
        try:
            _library, spec = BehaviorLibrary.for_file(path)
        except BehaviorError as error:
            failed = True
            for problem in error.problems:
                typer.echo(problem)
            continue
        if ruleset is not None:
            problems = decision_problems({spec.name: spec}, partial(check_outcomes, ruleset))
            if problems:
                failed = True
                for problem in problems:
                    typer.echo(problem)
                continue
        typer.echo(f"{path}: ok")
    if failed:
        raise typer.Exit(1)


RobotFactory = Callable[[int], RobotPort]
"""Makes the robot ``step`` and ``run`` drive, from the run's seed."""

_robot_factory: list[RobotFactory] = []


def use_robot(factory: RobotFactory) -> None:
    """Wire the robot ``step`` and ``run`` drive: the composition root (dms/cli.py) passes
    the simulated Mini, so that activities never import ``sim``."""
    _robot_factory[:] = [factory]


def _robot(seed: int) -> RobotPort:
    if not _robot_factory:
        typer.echo("no robot wired: run behaviors through `dms behavior`", err=True)
        raise typer.Exit(2)
    return _robot_factory[0](seed)


@app.command()
def show(
    file: Annotated[Path, typer.Argument(help="A behavior file.")],
    format: Annotated[
        DiagramFormat, typer.Option(help="dot, mermaid, or svg/png (drawn by Graphviz).")
    ] = DiagramFormat.DOT,
    active: Annotated[str, typer.Option(help="A state path to highlight.")] = "",
    output: Annotated[
        Path | None, typer.Option("--output", "-o", help="Write here instead of stdout.")
    ] = None,
) -> None:
    """A diagram of the behavior's states and transitions (nested machines as clusters)."""
    _library, spec = BehaviorLibrary.for_file(file)
    if format is DiagramFormat.MERMAID:
        data = to_mermaid(spec, active).encode()
    elif format is DiagramFormat.DOT:
        data = to_dot(spec, active).encode()
    else:
        if output is None and format is DiagramFormat.PNG and sys.stdout.isatty():
            typer.echo("dms: a PNG is not for a terminal: give --output FILE", err=True)
            raise typer.Exit(1)
        data = _render(to_dot(spec, active), format)
    if output is not None:
        output.write_bytes(data)
    else:
        sys.stdout.flush()
        sys.stdout.buffer.write(data)
        sys.stdout.buffer.flush()


@app.command()
def step(
    file: Annotated[Path, typer.Argument(help="A behavior file.")],
    user: Annotated[str | None, typer.Option(help="Run as this user (params.user).")] = None,
    seed: Annotated[int, typer.Option(help="Random seed.")] = 0,
    text: Annotated[str | None, typer.Option(help="args.text (for notification).")] = None,
) -> None:
    """Run on the simulated robot one state at a time: Enter goes on.

    At a question it waits for the answer: type it (said by the user), ``screen:CHOICE``
    to tap the screen, ``touch:PART`` to touch the robot, or ``skip`` to let it time
    out; ``q`` stops. Each step prints the state, what changed in the userdata and the
    robot's commands. At the end of input it runs on.
    """
    library, spec = BehaviorLibrary.for_file(file)
    run = BehaviorRun(
        library, spec, _robot(seed), _user(user), {"text": text} if text else {}, seed
    )
    _print(run.begin())
    interactive = True
    while not run.activity.finished:
        if interactive:
            typer.echo("> ", nl=False)
            line = sys.stdin.readline()
            if not line:
                interactive = False
            elif line.strip() == "q":
                run.activity.cancel(run.clock.now())
                break
            elif not line.strip() and run.awaiting_answer:
                typer.echo(f"  waiting for an answer: type it, or {SKIP!r} to let it time out")
                continue
            elif line.strip() == SKIP:
                pass  # on to the question's timeout
            else:
                try:
                    event = parse_input(line)
                except ValueError as error:
                    typer.echo(f"  not understood: {error}".splitlines()[0])
                    continue
                if event is not None:
                    taken = run.deliver(event)
                    typer.echo(f"  event {'taken' if taken else 'not taken'}")
        _print(run.next_state(max_s=600.0 if interactive else 3600.0))
    result = run.activity.result
    typer.echo(
        f"{run.activity.status.value if run.activity.status else '-'}: {result.outcome}"
        + (f" -> {result.redirect}" if result.redirect else "")
        + (f" ({result.error})" if result.error else "")
    )


@app.command("run")
def run_command(
    file: Annotated[Path, typer.Argument(help="A behavior file.")],
    user: Annotated[str | None, typer.Option(help="Run as this user (params.user).")] = None,
    answer: Annotated[
        list[str] | None, typer.Option(help="Answers to the questions, in order.")
    ] = None,
    seed: Annotated[int, typer.Option(help="Random seed.")] = 0,
    max_s: Annotated[float, typer.Option(help="Cancel after this many virtual seconds.")] = 3600,
    text: Annotated[str | None, typer.Option(help="args.text (for notification).")] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print only a JSON summary.")] = False,
) -> None:
    """Run the behavior to its end on the simulated robot and a virtual clock."""
    library, spec = BehaviorLibrary.for_file(file)
    run = BehaviorRun(
        library, spec, _robot(seed), _user(user), {"text": text} if text else {}, seed
    )
    steps: list[Step] = []
    activity = run.run(steps.append if as_json else _print, answer or [], max_s)
    result = activity.result
    summary = {
        "behavior": spec.name,
        "status": activity.status.value if activity.status else None,
        "outcome": result.outcome,
        "redirect": result.redirect,
        "error": result.error,
        "seconds": run.t,
        "states": len(steps),
        "commands": len(run.commands),
        "data": result.data,
    }
    if as_json:
        typer.echo(json.dumps(summary, default=str))
    else:
        typer.echo(f"{summary['status']}: {result.outcome} after {run.t:.1f} s")
    if result.error:
        raise typer.Exit(1)


@app.command()
def schema() -> None:
    """Print the JSON Schema of behavior files."""
    typer.echo(schema_text(), nl=False)
