"""``dms behavior``: check, draw, step through and run behavior files; print the schema."""

from __future__ import annotations

import difflib
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
from activities.library import (
    BEHAVIORS_DIR,
    BehaviorLibrary,
    OutcomeCheck,
    decision_problems,
    load_specs,
)
from activities.schema import schema_text
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


def behavior_file(given: Path) -> Path:
    """A behavior file given by its path, or by its name (``quiz``) in the shipped library.

    Raises:
        BehaviorError: a bare name that is no file and no shipped behavior; the message
            says which names there are.
    """
    if given.exists() or given.suffix or len(given.parts) != 1:
        return given
    name = str(given)
    known = sorted(path.stem for path in BEHAVIORS_DIR.glob("*.yaml"))
    if name in known:
        return BEHAVIORS_DIR / f"{name}.yaml"
    close = difflib.get_close_matches(name, known, n=1)
    hint = f"did you mean {close[0]!r}? " if close else ""
    raise BehaviorError(
        f"{name}: no such file, and no behavior of that name ({hint}behaviors: {', '.join(known)})"
    )


@app.command()
def check(
    files: Annotated[
        list[Path] | None,
        typer.Argument(help="Behavior files, names or folders (default: the shipped behaviors)."),
    ] = None,
    rules: Annotated[
        list[Path] | None,
        typer.Option(help="Rules files: decide states must declare every activation."),
    ] = None,
) -> None:
    """Check behavior files; one FILE:LINE: state PATH: message line per problem.

    A folder is checked as the daemon loads it (every file, and the references between
    them). With ``--rules``, a decide state whose DMSL component may activate something
    that is not among its outcomes is a problem too (the rules' own problems first).
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
    decisions = None if ruleset is None else partial(check_outcomes, ruleset)
    failed = False
    for given in files or [BEHAVIORS_DIR]:
        if given.is_dir():
            failed = not _check_folder(given, decisions) or failed
            continue
        try:
            path = behavior_file(given)
            _library, spec = BehaviorLibrary.for_file(path)
        except BehaviorError as error:
            failed = True
            for problem in error.problems:
                typer.echo(problem)
            continue
        problems = [] if decisions is None else decision_problems({spec.name: spec}, decisions)
        for problem in problems:
            typer.echo(problem)
        failed = failed or bool(problems)
        if not problems:
            typer.echo(f"{path}: ok")
    if failed:
        raise typer.Exit(1)


def _check_folder(folder: Path, decisions: OutcomeCheck | None) -> bool:
    """Check every behavior of ``folder`` together, as the daemon loads it: True if good."""
    specs, problems = load_specs(folder)
    if decisions is not None:
        problems.extend(decision_problems(specs, decisions))
    for problem in problems:
        typer.echo(problem)
    for path in sorted(folder.glob("*.yaml")):
        if not any(problem.startswith(f"{path}:") for problem in problems):
            typer.echo(f"{path}: ok")
    return not problems


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
    file: Annotated[Path, typer.Argument(help="A behavior file, or a behavior's name.")],
    format: Annotated[
        DiagramFormat, typer.Option(help="dot, mermaid, or svg/png (drawn by Graphviz).")
    ] = DiagramFormat.DOT,
    active: Annotated[str, typer.Option(help="A state path to highlight.")] = "",
    output: Annotated[
        Path | None, typer.Option("--output", "-o", help="Write here instead of stdout.")
    ] = None,
) -> None:
    """A diagram of the behavior's states and transitions (nested machines as clusters)."""
    _library, spec = BehaviorLibrary.for_file(behavior_file(file))
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
    file: Annotated[Path, typer.Argument(help="A behavior file, or a behavior's name.")],
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
    library, spec = BehaviorLibrary.for_file(behavior_file(file))
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
    file: Annotated[Path, typer.Argument(help="A behavior file, or a behavior's name.")],
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
    library, spec = BehaviorLibrary.for_file(behavior_file(file))
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
