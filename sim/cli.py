"""Command line of the sim package, mounted by dms.cli as ``dms sim`` (``dms record`` is
:mod:`sim.record_cli`)."""

from __future__ import annotations

import json
import signal
import sys
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING, Annotated, Any, Literal

import typer

from dms.kernel.cli_options import (
    DEFAULT_ENDPOINT,
    ConnectOption,
    DbOption,
    JsonOption,
    RobotOption,
)
from sim.errors import ExpectationFailed, SimError

if TYPE_CHECKING:
    from dms.config import Settings

app = typer.Typer(no_args_is_help=True)


def _print_json(payload: object) -> None:
    typer.echo(json.dumps(payload, indent=2))


def _stop_on_signals() -> threading.Event:
    """An event set by SIGINT or SIGTERM (the CLI's way to end a live command)."""
    stop = threading.Event()

    def handler(_signum: int, _frame: FrameType | None) -> None:
        stop.set()

    signal.signal(signal.SIGINT, handler)
    signal.signal(signal.SIGTERM, handler)
    return stop


@app.command("run")
def run_command(
    scenario: Annotated[str, typer.Argument(help="Scenario file (or a shipped scenario's name).")],
    as_json: JsonOption = False,
) -> None:
    """Replay a scripted session on the virtual clock; exit 1 naming the first failed check."""
    from sim.runner import run_scenario

    result = run_scenario(scenario)
    if as_json:
        _print_json(result.to_json())
    else:
        from dms.console import format_decision

        for timed in result.decisions:
            typer.echo(f"{timed.t:8.1f}s  {format_decision(timed.decision)}")
        for check in result.results:
            mark = "ok  " if check.passed else "FAIL"
            typer.echo(f"{mark} {check.description}: {check.detail}")
        typer.echo(
            f"{result.name}: {sum(r.passed for r in result.results)}/{len(result.results)} "
            f"expectations hold ({result.ticks} ticks, {result.wall_s:.2f} s)"
        )
    failure = result.first_failure
    if failure is not None:
        line = f":{failure.line}" if failure.line else ""
        raise ExpectationFailed(
            f"{result.path}{line}: expectation {failure.index} failed: "
            f"{failure.description}: {failure.detail}"
        )


def _design(config: Path | None, rules: Path | None) -> tuple[Settings, dict[str, Any]]:
    """The settings of ``--config`` (as ``dms run --config`` reads them) with ``--rules``
    in place of its rule files, never its database (a simulation has its own), and the
    TOML as read (to tell which settings the file gives)."""
    from dms.config import Settings, load_config
    from dms.kernel.tomlfile import read_toml

    settings = load_config(config) if config is not None else Settings()
    raw = read_toml(config) if config is not None else {}
    update: dict[str, Any] = {"db": None}
    if rules is not None:
        if not rules.is_file():
            raise SimError(f"--rules: {rules} is not a file")
        update["rules"] = settings.rules.model_copy(update={"files": [rules]})
    return settings.model_copy(update=update), raw


@contextmanager
def _progress(total: int, what: str) -> Iterator[Callable[[int], None]]:
    """A progress bar with the time left on stderr (stdout stays clean for --json);
    yields the callback to tell it how many are done."""
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TimeRemainingColumn

    columns = (
        "{task.description}",
        BarColumn(),
        MofNCompleteColumn(),
        "time left",
        TimeRemainingColumn(),
    )
    with Progress(*columns, console=Console(stderr=True), transient=False) as bar:
        task = bar.add_task(what, total=total)
        yield lambda done: bar.update(task, completed=done)


ConfigOption = Annotated[
    Path | None, typer.Option("--config", help="A dms TOML configuration (as dms run --config).")
]
RulesOption = Annotated[
    Path | None, typer.Option("--rules", help="A DMSL rules file, in place of the config's.")
]


ChooserOption = Literal[
    "dms", "explore", "random", "fixed", "popular", "greedy", "least_liked", "oracle"
]
PopulationOption = Literal["paper", "personas", "heldout"]


def _seeds(text: str | None) -> list[int] | None:
    """``0-99`` or ``0,3,7`` as a list of seeds (None: not given)."""
    if text is None:
        return None
    try:
        if "-" in text:
            first, last = text.split("-", 1)
            seeds = list(range(int(first), int(last) + 1))
        else:
            seeds = [int(part) for part in text.split(",")]
    except ValueError:
        raise typer.BadParameter(
            "give FIRST-LAST or a comma-separated list", param_hint="--seeds"
        ) from None
    if not seeds:
        raise typer.BadParameter("no seed in the range", param_hint="--seeds")
    return seeds


SeedsOption = Annotated[
    str | None,
    typer.Option(
        "--seeds",
        help="Run one study per seed (FIRST-LAST or a list) and report each metric's mean "
        "with its 95 % interval; the reported figures use 0-99.",
        show_default=False,
    ),
]


ParticipantsOption = Annotated[
    Path | None,
    typer.Option(
        "--participants",
        help="Draw the participants' habits from this file (made by dms sim fit) instead "
        "of sim/calibration.py's values.",
    ),
]


def _calibration(participants: Path | None) -> Any:
    """The study's inputs: sim/calibration.py's, with a participants file's estimates."""
    from sim.calibration import DEFAULT

    if participants is None:
        return DEFAULT
    from sim.fit import load_participants

    calibration, used = load_participants(participants)
    print(f"dms: participants' inputs from {participants}: {', '.join(used)}", file=sys.stderr)
    return calibration


@app.command("study")
def study_command(
    sessions: Annotated[int, typer.Option(min=1, max=10000, help="Participants.")] = 30,
    minutes: Annotated[float, typer.Option(min=0.5, max=24 * 60, help="Session length.")] = 30.0,
    proactivity: Annotated[
        Literal["low", "moderate", "high"],
        typer.Option(help="True proactivity of every participant."),
    ] = "moderate",
    seed: Annotated[int, typer.Option(help="Random seed.")] = 0,
    seeds: SeedsOption = None,
    repeat: Annotated[
        int, typer.Option(min=1, max=100, help="Visits of each participant (adaptation).")
    ] = 1,
    population: Annotated[
        PopulationOption,
        typer.Option(
            help="paper (adults like the paper's, tastes from the learner's data's world), "
            "heldout (tastes of another structure) or personas (the shipped ones)."
        ),
    ] = "paper",
    chooser: Annotated[
        ChooserOption,
        typer.Option(help="What picks the robot's own choices: the decision system or a baseline."),
    ] = "dms",
    config: ConfigOption = None,
    rules: RulesOption = None,
    out: Annotated[
        Path | None,
        typer.Option(
            "--out", help="Folder for sessions.csv, decisions.csv, events.csv and table4.png."
        ),
    ] = None,
    participants: ParticipantsOption = None,
    as_json: Annotated[
        bool, typer.Option("--json", help="Print JSON (docs/contract.md's keys).")
    ] = False,
) -> None:
    """The paper's first experiment with simulated participants; prints its Table 4."""
    from sim.study import run_study, study_settings

    settings, raw = _design(config, rules)
    calibration = _calibration(participants)
    chosen = _seeds(seeds)
    if chosen is not None:
        from sim.prediction import run_seeds, summary, table

        with _progress(len(chosen), "studies") as told:
            results = run_seeds(
                chosen,
                sessions,
                minutes,
                proactivity,
                study_settings(settings, raw),
                chooser=chooser,
                population=population,
                calibration=calibration,
                progress=told,
            )
        estimates = summary(results)
        if as_json:
            _print_json(
                {
                    "seeds": chosen,
                    "chooser": chooser,
                    "population": population,
                    "metrics": {key: e.to_json() for key, e in estimates.items()},
                }
            )
        else:
            typer.echo(table(estimates, chosen))
        return
    with _progress(sessions * repeat, "sessions") as told:
        result = run_study(
            sessions,
            minutes,
            proactivity,
            seed,
            study_settings(settings, raw),
            told,
            repeat=repeat,
            population=population,
            record_decisions=out is not None,
            chooser=chooser,
            calibration=calibration,
            record_events=out is not None,
        )
    if out is not None:
        from sim.export import write_all
        from sim.fit import write_events

        for path in write_all(out, result.sessions, result.decisions):
            print(f"dms: wrote {path}", file=sys.stderr)
        print(f"dms: wrote {write_events(out / 'events.csv', result.events)}", file=sys.stderr)
    if as_json:
        _print_json(result.to_json())
    else:
        typer.echo(result.table())


@app.command("compare")
def compare_command(
    design_a: Annotated[
        Path | None, typer.Argument(help="Design A: a dms TOML configuration (default: none).")
    ] = None,
    design_b: Annotated[
        Path | None, typer.Argument(help="Design B: a dms TOML configuration (default: A's).")
    ] = None,
    rules_a: Annotated[Path | None, typer.Option("--rules-a", help="Rules file of A.")] = None,
    rules_b: Annotated[Path | None, typer.Option("--rules-b", help="Rules file of B.")] = None,
    chooser_a: Annotated[ChooserOption, typer.Option("--chooser-a", help="A's chooser.")] = "dms",
    chooser_b: Annotated[ChooserOption, typer.Option("--chooser-b", help="B's chooser.")] = "dms",
    sessions: Annotated[int, typer.Option(min=2, max=10000, help="Participants.")] = 30,
    minutes: Annotated[float, typer.Option(min=0.5, max=24 * 60, help="Session length.")] = 30.0,
    seed: Annotated[int, typer.Option(help="Random seed (the same for both).")] = 0,
    seeds: SeedsOption = None,
    population: Annotated[
        PopulationOption, typer.Option(help="The participants (as dms sim study's).")
    ] = "paper",
    repeat: Annotated[
        int,
        typer.Option(
            min=1, max=100, help="Visits of each participant; every metric is also given per visit."
        ),
    ] = 1,
    participants: ParticipantsOption = None,
    as_json: JsonOption = False,
) -> None:
    """Run two designs or choosers on the same participants; per metric, both means and
    the paired difference (B - A) with a bootstrap 95 % interval, pooled and per visit."""
    from sim.compare import compare, table, to_json
    from sim.study import study_settings

    settings_a, raw_a = _design(design_a, rules_a)
    settings_b, raw_b = _design(design_b if design_b is not None else design_a, rules_b)
    calibration = _calibration(participants)
    chosen = _seeds(seeds)
    runs = len(chosen) if chosen is not None else 1
    with _progress(2 * sessions * repeat * runs, "sessions (A, then B)") as told:
        done = {"A": 0, "B": 0}

        def progress(label: str, count: int) -> None:
            done[label] = count
            told(done["A"] + done["B"])

        result = compare(
            study_settings(settings_a, raw_a),
            study_settings(settings_b, raw_b),
            sessions,
            minutes,
            seed,
            progress=progress,
            chooser_a=chooser_a,
            chooser_b=chooser_b,
            seeds=chosen,
            population=population,
            calibration=calibration,
            repeat=repeat,
        )
    if as_json:
        _print_json(to_json(result))
    else:
        typer.echo(table(result))


@app.command("fit")
def fit_command(
    events: Annotated[
        Path | None,
        typer.Argument(help="An events table: dms sessions export --events --format csv."),
    ] = None,
    db: DbOption = None,
    since: Annotated[
        str | None, typer.Option("--since", help="With --db: sessions from this date (ISO, UTC).")
    ] = None,
    out: Annotated[
        Path, typer.Option("--out", help="The participants file to write (YAML).")
    ] = Path("participants.yaml"),
    bootstrap: Annotated[
        int, typer.Option(min=50, max=100000, help="Resamples of the people.")
    ] = 400,
    seed: Annotated[int, typer.Option(help="Seed of the resampling.")] = 0,
    as_json: JsonOption = False,
) -> None:
    """Estimate the simulated participants' inputs (delays, patience, speech, proactivity)
    from recorded sessions, each with its bootstrap interval; write a participants file."""
    from sim import fit

    if (events is None) == (db is None):
        raise typer.BadParameter("give an events table or --db (one of them)")
    if events is not None:
        rows, origin = fit.read_table(events), str(events)
    else:
        from memory.sessions_cli import read_events

        rows, origin = read_events(db, since), "the database's sessions"
    persons = fit.people(rows)
    fitted = fit.fit(persons, bootstrap=bootstrap, seed=seed, origin=origin)
    fit.write_participants(out, fitted, len(persons), origin)
    print(f"dms: wrote {out}", file=sys.stderr)
    if as_json:
        _print_json({item.name: fit.entry(item) for item in fitted})
        return
    typer.echo(fit.table(fitted, len(persons)))


@app.command("sensitivity")
def sensitivity_command(
    sessions: Annotated[int, typer.Option(min=2, max=10000, help="Participants.")] = 30,
    minutes: Annotated[float, typer.Option(min=0.5, max=24 * 60, help="Session length.")] = 30.0,
    seeds: SeedsOption = "0-9",
    change: Annotated[
        float, typer.Option(min=0.01, max=0.99, help="Move each input by this share.")
    ] = 0.5,
    only: Annotated[
        list[str] | None, typer.Option("--only", help="Sweep only this input (repeatable).")
    ] = None,
    out: Annotated[
        Path, typer.Option("--out", help="Folder for sensitivity.csv and sensitivity.png.")
    ] = Path("sensitivity"),
    population: Annotated[
        PopulationOption, typer.Option(help="The participants (as dms sim study's).")
    ] = "paper",
    chooser: Annotated[
        ChooserOption, typer.Option(help="What picks the robot's own choices (as dms sim study's).")
    ] = "dms",
    jobs: Annotated[
        int, typer.Option(min=1, max=64, help="Studies run at once (worker processes).")
    ] = 1,
    as_json: JsonOption = False,
) -> None:
    """Move each input of the study (the participants', the robot's, the protocol's, the
    content's and the controller's settings) by ±50 % and show which Table 4 metric moves
    with it, above each metric's noise floor over the seeds (a CSV and a tornado chart)."""
    from sim.sensitivity import SWEEPABLE, sweep, write_csv, write_tornado

    chosen = _seeds(seeds) or [0]
    names = list(only) if only else list(SWEEPABLE)
    unknown = [name for name in names if name not in SWEEPABLE]
    if unknown:
        raise typer.BadParameter(
            f"{', '.join(unknown)}: not an input of the study ({', '.join(SWEEPABLE)})",
            param_hint="--only",
        )
    with _progress(len(chosen) * (1 + 2 * len(names)), "studies") as told:
        result = sweep(
            names,
            chosen,
            sessions,
            minutes,
            change,
            progress=told,
            chooser=chooser,
            population=population,
            jobs=jobs,
        )
    out.mkdir(parents=True, exist_ok=True)
    paths = [
        write_csv(out / "sensitivity.csv", result),
        write_tornado(out / "sensitivity.png", result),
    ]
    for path in paths:
        print(f"dms: wrote {path}", file=sys.stderr)
    if as_json:
        _print_json(result.to_json())
    else:
        typer.echo(result.text())


@app.command("longterm")
def longterm_command(
    days: Annotated[int, typer.Option(min=1, max=3660, help="Days of robot life.")] = 30,
    users: Annotated[int, typer.Option(min=0, max=100, help="Simulated users visiting.")] = 3,
    seed: Annotated[int, typer.Option(help="Random seed.")] = 0,
    out: Annotated[
        Path,
        typer.Option(help="Folder for the plots, sessions.csv, decisions.csv and table4.png."),
    ] = Path("longterm"),
    config: ConfigOption = None,
    rules: RulesOption = None,
    as_json: Annotated[
        bool, typer.Option("--json", help="Print JSON (docs/contract.md's keys).")
    ] = False,
) -> None:
    """Weeks of robot life with users visiting; plots drives, wellbeing and activities."""
    from sim.longterm import run_longterm

    settings = _design(config, rules)[0] if config is not None or rules is not None else None
    with _progress(days, "days") as told:
        result = run_longterm(days, users, seed, out, settings=settings, progress=told)
    if as_json:
        _print_json(result.to_json())
        return
    typer.echo(
        f"{days} days, users {', '.join(result.users) or 'none'}: {result.visits} visits, "
        f"{result.decisions} decisions, {result.ticks} ticks in {result.wall_s:.1f} s, "
        f"peak RSS {result.peak_rss_mb:.0f} MB"
    )
    typer.echo(
        f"wellbeing mean {result.wellbeing_mean:.1f}; drives max "
        + ", ".join(f"{name} {value:.1f}" for name, value in sorted(result.drives_max.items()))
    )
    top = sorted(result.activity_seconds.items(), key=lambda item: -item[1])
    typer.echo("time by activity: " + ", ".join(f"{n} {s / 3600:.1f} h" for n, s in top))
    for path in result.plots:
        typer.echo(f"wrote {path}")


@app.command("replay")
def replay_command(
    recording: Annotated[Path, typer.Argument(help="An MCAP file written by dms record.")],
    seed: Annotated[
        int | None,
        typer.Option(help="Seed of the replayed controller (default: the recorded one, else 0)."),
    ] = None,
    config: Annotated[
        Path | None,
        typer.Option(help="A TOML configuration in place of the recorded daemon's."),
    ] = None,
    as_json: JsonOption = False,
) -> None:
    """Feed a recording's inputs through the controller and report differing decisions.

    Exit 0 when the replayed decisions are the recorded ones, 1 when they differ.
    """
    from dms.config import load_config
    from sim.replay import replay

    settings = load_config(config, use_environment=False) if config is not None else None
    if settings is not None:
        settings = settings.model_copy(update={"db": None})  # never the recorded store
    if seed is None and settings is not None:
        seed = settings.seed
    report = replay(recording, seed=seed, settings=settings)
    if as_json:
        _print_json(report.to_json())
    else:
        typer.echo(report.text())
    if report.truncated:
        print(f"dms: {recording}: truncated: {report.truncated}", file=sys.stderr)
    if not report.same:
        first = report.differences[0]
        raise SimError(
            f"{recording}: {len(report.differences)} difference(s) from the recorded "
            f"decisions, the first at {first.time}"
        )


@app.command("robot")
def robot_command(
    robot_id: RobotOption = "mini",
    connect: ConnectOption = None,
    listen: Annotated[list[str] | None, typer.Option(help="Zenoh endpoint to listen on.")] = None,
    seed: Annotated[int, typer.Option(help="Seed of the simulated robot.")] = 0,
    duration: Annotated[float | None, typer.Option(min=0.0, help="Stop after S seconds.")] = None,
) -> None:
    """The simulated Mini as its own process: executes robot/command, publishes robot/feedback."""
    from dms.bus import ZenohClient, make_config
    from dms.kernel.clock import RealClock
    from dms.kernel.keys import ROBOT_ID_RE
    from sim.robot_node import RobotNode

    if not ROBOT_ID_RE.fullmatch(robot_id):
        raise SimError(f"--robot-id: {robot_id!r} does not match [a-z0-9_-]+")
    endpoints = connect if connect or listen else [DEFAULT_ENDPOINT]
    with ZenohClient(robot_id, make_config(listen=listen or (), connect=endpoints or ())) as client:
        node = RobotNode(client, RealClock(), seed)
        stop = _stop_on_signals()

        def relay() -> None:
            stop.wait()
            node.stopped.set()

        threading.Thread(target=relay, daemon=True).start()
        print(f"dms: simulated robot {robot_id} serving; Ctrl-C stops", file=sys.stderr)
        node.run(duration)
        node.stopped.set()
        stop.set()
    print(f"dms: {node.commands} commands, {node.feedback} feedback messages", file=sys.stderr)


@app.command("personas")
def personas_command() -> None:
    """List the shipped personas (a table: name, proactivity, description)."""
    from memory.cli import print_table
    from sim.persona import load_persona, shipped_personas

    rows = []
    for name in shipped_personas():
        persona = load_persona(name)
        rows.append([name, persona.proactivity, persona.description])
    print_table(None, ["name", "proactivity", "description"], rows)


__all__ = ["app"]
