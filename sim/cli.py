"""Command line of the sim package, mounted by dms.cli as ``dms sim`` and ``dms record``."""

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

from sim.errors import ExpectationFailed, SimError

if TYPE_CHECKING:
    from dms.bus import ZenohClient
    from dms.config import Settings
    from sim.recording import McapRecorder

app = typer.Typer(no_args_is_help=True)

DEFAULT_ENDPOINT = "tcp/127.0.0.1:7447"


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
    as_json: Annotated[bool, typer.Option("--json", help="Print the result as JSON.")] = False,
) -> None:
    """Replay a scripted session on the virtual clock; exit 1 naming the first failed check."""
    from sim.runner import run_scenario

    result = run_scenario(scenario)
    if as_json:
        _print_json(result.to_json())
    else:
        from dms.daemon import format_decision

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


@app.command("study")
def study_command(
    sessions: Annotated[int, typer.Option(min=1, max=10000, help="Participants.")] = 30,
    minutes: Annotated[float, typer.Option(min=0.5, max=24 * 60, help="Session length.")] = 30.0,
    proactivity: Annotated[
        Literal["low", "moderate", "high"],
        typer.Option(help="True proactivity of every participant."),
    ] = "moderate",
    seed: Annotated[int, typer.Option(help="Random seed.")] = 0,
    repeat: Annotated[
        int, typer.Option(min=1, max=100, help="Visits of each participant (adaptation).")
    ] = 1,
    population: Annotated[
        Literal["paper", "personas"],
        typer.Option(help="paper (adults like the seed's) or personas (the shipped ones)."),
    ] = "paper",
    config: ConfigOption = None,
    rules: RulesOption = None,
    out: Annotated[
        Path | None,
        typer.Option("--out", help="Folder for sessions.csv, decisions.csv and table4.png."),
    ] = None,
    as_json: Annotated[
        bool, typer.Option("--json", help="Print JSON (CONTRACT.md's keys).")
    ] = False,
) -> None:
    """The seed's first experiment with simulated participants; prints its Table 4."""
    from sim.study import run_study, study_settings

    settings, raw = _design(config, rules)
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
        )
    if out is not None:
        from sim.export import write_all

        for path in write_all(out, result.sessions, result.decisions):
            print(f"dms: wrote {path}", file=sys.stderr)
    if as_json:
        _print_json(result.to_json())
    else:
        typer.echo(result.table())


@app.command("compare")
def compare_command(
    design_a: Annotated[Path, typer.Argument(help="Design A: a dms TOML configuration.")],
    design_b: Annotated[Path, typer.Argument(help="Design B: a dms TOML configuration.")],
    rules_a: Annotated[Path | None, typer.Option("--rules-a", help="Rules file of A.")] = None,
    rules_b: Annotated[Path | None, typer.Option("--rules-b", help="Rules file of B.")] = None,
    sessions: Annotated[int, typer.Option(min=2, max=10000, help="Participants.")] = 30,
    minutes: Annotated[float, typer.Option(min=0.5, max=24 * 60, help="Session length.")] = 30.0,
    seed: Annotated[int, typer.Option(help="Random seed (the same for both).")] = 0,
    as_json: Annotated[bool, typer.Option("--json", help="Print JSON.")] = False,
) -> None:
    """Run two designs on the same participants; per metric, both means and the paired
    difference (B - A) with a bootstrap 95 % interval."""
    from sim.compare import compare, table, to_json
    from sim.study import study_settings

    settings_a, raw_a = _design(design_a, rules_a)
    settings_b, raw_b = _design(design_b, rules_b)
    with _progress(2 * sessions, "sessions (A, then B)") as told:
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
        )
    if as_json:
        _print_json(to_json(result))
    else:
        typer.echo(table(result))


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
        bool, typer.Option("--json", help="Print JSON (CONTRACT.md's keys).")
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
    as_json: Annotated[bool, typer.Option("--json", help="Print the report as JSON.")] = False,
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
    robot_id: Annotated[str, typer.Option("--robot-id", help="Robot id.")] = "mini",
    connect: Annotated[list[str] | None, typer.Option(help="Zenoh endpoint to connect to.")] = None,
    listen: Annotated[list[str] | None, typer.Option(help="Zenoh endpoint to listen on.")] = None,
    seed: Annotated[int, typer.Option(help="Seed of the simulated robot.")] = 0,
    duration: Annotated[float | None, typer.Option(min=0.0, help="Stop after S seconds.")] = None,
) -> None:
    """The simulated Mini as its own process: executes robot/command, publishes robot/feedback."""
    from dms.bus import ZenohClient, make_config
    from dms.kernel.clock import RealClock
    from dms.kernel.keys import ROBOT_ID_RE
    from sim.robot_node import RobotNode

    if not ROBOT_ID_RE.match(robot_id):
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


record_app = typer.Typer()


@record_app.callback(invoke_without_command=True)
def record_command(
    ctx: typer.Context,
    out: Annotated[
        Path | None, typer.Option("--out", help="The MCAP file to write.", show_default=False)
    ] = None,
    robot_id: Annotated[
        str, typer.Option("--robot-id", envvar="DMS_ROBOT_ID", help="Robot id.")
    ] = "mini",
    connect: Annotated[
        list[str] | None,
        typer.Option(
            help=f"Zenoh endpoint to connect to (default {DEFAULT_ENDPOINT}).", show_default=False
        ),
    ] = None,
    zenoh_config: Annotated[
        Path | None,
        typer.Option("--zenoh-config", help="Zenoh JSON5 configuration file.", show_default=False),
    ] = None,
    duration: Annotated[
        float | None,
        typer.Option(
            min=0.0, help="Stop after S seconds (else on SIGINT/SIGTERM).", show_default=False
        ),
    ] = None,
) -> None:
    """Record every message under robots/<id>/** into MCAP; dms record info FILE describes one.

    JSON with its schemas (for Foxglove) in zstd chunks, with the daemon's seed, settings
    and files, so that dms sim replay FILE needs no flags. Exit 1 when nothing was recorded.
    """
    if ctx.invoked_subcommand is not None:
        return
    import time

    from dms.bus import ZenohClient, make_config
    from dms.kernel.keys import ROBOT_ID_RE
    from sim.recording import McapRecorder, record_until

    if out is None:
        raise typer.BadParameter(
            "give the file to write (or: dms record info FILE)", param_hint="--out"
        )
    if not ROBOT_ID_RE.match(robot_id):
        raise SimError(f"--robot-id: {robot_id!r} does not match [a-z0-9_-]+")
    endpoints = list(connect or ([] if zenoh_config else [DEFAULT_ENDPOINT]))
    config = make_config(connect=endpoints, config_file=zenoh_config)  # a bad file: one line
    recorder = McapRecorder(out, robot_id)  # a bad --out fails before the network is touched
    started = time.monotonic()
    try:
        stop = _stop_on_signals()
        with ZenohClient(robot_id, config) as client:
            print(f"dms: recording robots/{robot_id}/** into {out}; Ctrl-C stops", file=sys.stderr)
            asked = threading.Event()
            fetcher = threading.Thread(
                target=_store_config, args=(client, recorder, stop, asked), daemon=True
            )

            def subscribe(key_expr: str, handler: Callable[[str, bytes], None]) -> None:
                client.subscribe_raw(key_expr, handler)
                fetcher.start()  # asked after subscribing: its answer comes on a live link

            stats = record_until(recorder, subscribe, time.time_ns, stop, duration)
            asked.set()  # the recording is closed: stop asking
    finally:
        recorder.close()
    where = ", ".join(endpoints) or f"the endpoints of {zenoh_config}"
    if stats.messages == 0:
        out.unlink(missing_ok=True)
        raise SimError(
            f"recorded nothing from robots/{robot_id}/** in {time.monotonic() - started:.1f} s"
            f" (is its daemon running and reachable at {where}?); {out} not kept"
        )
    by_key = ", ".join(f"{key} {count}" for key, count in sorted(stats.by_key.items()))
    stored = "" if stats.configured else "; the daemon's configuration was not stored"
    print(f"dms: {stats.messages} messages recorded ({by_key}){stored}", file=sys.stderr)


def _store_config(
    client: ZenohClient, recorder: McapRecorder, stop: threading.Event, done: threading.Event
) -> None:
    """Once the daemon is alive, ask it for ``dms/config`` and store its answer (the seed,
    settings and files a replay needs); a daemon that does not answer leaves it out."""
    import time

    from dms.daemon import CONFIG_KEY
    from dms.kernel.keys import ALIVE_DMS

    while not (stop.is_set() or done.is_set()):
        if not client.wait_alive(ALIVE_DMS, 0.5):
            continue
        try:
            replies = client.query(CONFIG_KEY, timeout_s=10.0)
        except Exception:  # the session closed under the query: the recording has ended
            return
        for ok, body in replies:
            if ok and isinstance(body, dict) and recorder.add_config(body, time.time_ns()):
                files = body.get("files") or []
                print(
                    f"dms: stored robot {recorder.robot_id}'s configuration for replay "
                    f"(seed {body.get('seed')}, {len(files)} files)",
                    file=sys.stderr,
                    flush=True,
                )
                return
        return


@record_app.command("info")
def record_info_command(
    file: Annotated[Path, typer.Argument(help="An MCAP file written by dms record.")],
    as_json: Annotated[bool, typer.Option("--json", help="Print the description as JSON.")] = False,
) -> None:
    """Describe a recording, as ros2 bag info does.

    Its duration, messages per topic, chunks and their compression, and the daemon's
    configuration stored for replay.
    """
    from sim.recording import recording_info

    info = recording_info(file)
    if as_json:
        _print_json(info)
        return
    typer.echo(_info_text(info))


def _info_text(info: dict[str, Any]) -> str:
    from datetime import UTC, datetime

    def when(ns: int | None) -> str:
        if ns is None:
            return "-"
        return datetime.fromtimestamp(ns / 1e9, UTC).isoformat(timespec="milliseconds")

    start, end = info.get("start_ns"), info.get("end_ns")
    duration = (end - start) / 1e9 if start is not None and end is not None else 0.0
    lines = [
        f"File:          {info['file']}",
        f"Size:          {_size(info['bytes'])}",
        f"Duration:      {duration:.3f} s",
        f"Start:         {when(start)}",
        f"End:           {when(end)}",
        f"Messages:      {info['messages']}",
    ]
    if info.get("complete"):
        ratio = info["uncompressed_bytes"] / max(1, info["compressed_bytes"])
        lines.append(
            f"Chunks:        {info['chunks']} ({', '.join(info['compression']) or 'none'}; "
            f"{_size(info['uncompressed_bytes'])} -> {_size(info['compressed_bytes'])}, "
            f"{ratio:.1f}x)"
        )
    else:
        lines.append(f"Truncated:     {info.get('truncated')}")
    config = info.get("config")
    if config is None:
        lines.append("Configuration: not stored (dms sim replay needs --config and --seed)")
    else:
        versions = ", ".join(f"{k} {v}" for k, v in config["versions"].items())
        lines.append(f"Robot:         {config['robot_id']}")
        lines.append(f"Seed:          {config['seed'] if config['seed'] is not None else 'none'}")
        lines.append(f"Versions:      {versions}")
        files = config["files"]
        groups: dict[str, int] = {}
        for name in files:
            groups[name.split("/", 1)[0]] = groups.get(name.split("/", 1)[0], 0) + 1
        rules = [name.split("/")[-1] for name in files if name.startswith("rules/")]
        shown = ", ".join(f"{group} {count}" for group, count in sorted(groups.items()))
        lines.append(f"Files stored:  {len(files)} ({shown or 'none'})")
        if rules:
            lines.append(f"Rules:         {', '.join(rules)}")
    topics = info["topics"]
    width = max((len(t["topic"]) for t in topics), default=0)
    lines.append("Topics:" if topics else "Topics:        none")
    for topic in topics:
        schema = topic["schema"] or "-"
        lines.append(f"  {topic['topic']:<{width}}  {topic['count']:>7}  {schema}")
    return "\n".join(lines)


def _size(count: int) -> str:
    value = float(count)
    for unit in ("B", "KiB", "MiB", "GiB"):
        if value < 1024 or unit == "GiB":
            return f"{value:.0f} {unit}" if unit == "B" else f"{value:.1f} {unit}"
        value /= 1024
    return f"{count} B"


__all__ = ["app", "record_app", "record_command"]
