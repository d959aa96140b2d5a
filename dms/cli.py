"""The ``dms`` console script: one typer app with a sub-app per package.

``main`` runs it so that every failure a person can cause (a bad flag, a bad file,
a database that cannot be opened) ends as one ``dms: ...`` line on stderr and a
non-zero exit, never a traceback. ``dms --version`` prints the installed version;
``dms --install-completion`` installs typer's shell completion (bash, zsh, fish).

Each package's sub-app is imported only when its name is on the command line (see
``_Later``), and every command imports its own needs inside it: ``dms --version`` and
``dms --help`` then load typer and nothing of the decision stack.
"""

from __future__ import annotations

import gc
import os
import signal
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING, Annotated, Any, Literal

import typer
from typer.core import TyperCommand, TyperGroup

from dms.face.cli import face_command
from dms.fleet_cli import router as router_command
from dms.foxglove_cli import foxglove as foxglove_command
from dms.kernel.cli_options import DbOption
from dms.kernel.errors import DmsError
from dms.operator_cli import echo_command, request_command, state_command, topics_command
from dms.reachy_cli import reachy as reachy_command
from dms.ros2_cli import ros2 as ros2_command
from dms.studio.cli import studio_command
from dms.studio.cli import use_robot as use_studio_robot
from dms.viewer.cli import view_command

if TYPE_CHECKING:
    from typer._click import Command, Context

    from dms.config import Settings
    from dms.kernel.ports import RobotPort


@dataclass(frozen=True)
class SubApp:
    """A package's sub-app as ``dms --help`` lists it, and how to import it."""

    name: str
    summary: str
    load: Callable[[], typer.Typer]
    own_help: bool = False
    """Its help is its callback's docstring (``summary`` is then only the listing's line)."""


class _Later(TyperCommand):
    """A sub-app in ``dms --help`` and in shell completion, before it is imported."""

    def __init__(self, sub: SubApp) -> None:
        super().__init__(sub.name, help=sub.summary)
        self.sub = sub

    def load(self) -> Command:
        """The sub-app's command group, mounted as ``app.add_typer`` would mount it."""
        parent = typer.Typer()
        if self.sub.own_help:
            parent.add_typer(self.sub.load(), name=self.sub.name)
        else:
            parent.add_typer(self.sub.load(), name=self.sub.name, help=self.sub.summary)
        return typer.main.get_group(parent).commands[self.sub.name]


class _Group(TyperGroup):
    """The ``dms`` group: it lists every sub-app and imports only the one being run."""

    def __init__(self, **attrs: Any) -> None:
        super().__init__(**attrs)
        for sub in SUB_APPS:
            self.add_command(_Later(sub))

    def resolve_command(
        self, ctx: Context, args: list[str]
    ) -> tuple[str | None, Command | None, list[str]]:
        name, command, rest = super().resolve_command(ctx, args)
        if isinstance(command, _Later):
            command = command.load()
        return name, command, rest


app = typer.Typer(
    name="dms",
    cls=_Group,
    help="A biologically inspired decision daemon for social robots like Mini.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=True,
)


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("dms")
    except PackageNotFoundError:  # a source tree that was never installed
        return "unknown (not installed)"


def _show_version(value: bool) -> None:
    if value:
        typer.echo(f"dms {_version()}")
        raise typer.Exit(0)


@app.callback()
def _main(
    _version_flag: Annotated[
        bool,
        typer.Option(
            "--version",
            callback=_show_version,
            is_eager=True,
            help="Print the version and exit.",
        ),
    ] = False,
) -> None:
    """A biologically inspired decision daemon for social robots like Mini."""


db_app = typer.Typer(no_args_is_help=True)


@db_app.callback()
def _db() -> None:
    """Database schema migrations (a group, even with one command)."""


@db_app.command("upgrade")
def upgrade(
    db: DbOption = None,
) -> None:
    """Bring the database's schema (profiles and agenda) to the newest version.

    Each package owns its migrations; the composition root runs them all, in order.
    """
    from sqlalchemy.exc import SQLAlchemyError

    from agenda import migrations as agenda_migrations
    from memory.cli import refuse_newer, upgrade_profiles
    from memory.db import default_url
    from memory.errors import ProfileError, one_line

    url = db or default_url()
    refuse_newer(agenda_migrations.HISTORY, url, "agenda")  # before any change is made
    for line in upgrade_profiles(url):
        typer.echo(line)
    try:
        agenda_migrations.upgrade(url)
    except (SQLAlchemyError, ImportError, OSError) as error:
        raise ProfileError(f"cannot upgrade the agenda in {url}: {one_line(error)}") from None
    typer.echo("agenda: at head")


def _simulated_robot(seed: int) -> RobotPort:
    """The robot ``dms behavior step|run`` drives: the simulated Mini (imported when used)."""
    from sim.robot import SimRobot

    return SimRobot(rng_seed=seed)


def wire_simulated_robot() -> None:
    """Let ``dms behavior step|run`` drive the simulated Mini (activities never import sim)."""
    from activities.cli import use_robot

    use_robot(_simulated_robot)


def _rules() -> typer.Typer:
    from dms.rules_cli import app as rules_app

    return rules_app


def _users() -> typer.Typer:
    from memory.cli import app as users_app

    return users_app


def _sessions() -> typer.Typer:
    from memory.sessions_cli import app as sessions_app

    return sessions_app


def install_catalogue_of(behaviors: Path | None, config: Path | None) -> None:
    """Put in force the activities a daemon would have: those of the ``behaviors``
    folder, else of the folder ``config`` (and the DMS_* variables) name, as ``dms run``
    loads them. For the commands that open the database or read the daemon's file
    without a daemon (an event naming a declared activity, a declared relax drive)."""
    from activities.errors import BehaviorError
    from activities.library import BehaviorLibrary
    from dms.config import load_config
    from dms.kernel.errors import ConfigError

    if behaviors is not None and not behaviors.is_dir():
        raise ConfigError(f"--behaviors: {behaviors} is not a directory")
    folder = behaviors if behaviors is not None else load_config(config).behaviors.folder
    try:
        BehaviorLibrary.load(folder).install_catalogue()
    except BehaviorError as error:
        where = "--behaviors" if behaviors is not None else str(config or "DMS_BEHAVIORS__FOLDER")
        raise ConfigError(f"{where}: {error}") from None


def _agenda() -> typer.Typer:
    from agenda.cli import app as agenda_app
    from agenda.cli import use_catalogue_loader

    use_catalogue_loader(install_catalogue_of)
    return agenda_app


def _motivation() -> typer.Typer:
    from motivation.cli import app as motivation_app
    from motivation.cli import use_catalogue_loader

    use_catalogue_loader(install_catalogue_of)
    return motivation_app


def _behavior() -> typer.Typer:
    from activities.cli import app as behavior_app

    wire_simulated_robot()
    return behavior_app


SIM_EXTRAS = ("matplotlib", "scipy")
"""What ``pip install 'dms[sim]'`` adds to the daemon's install: plots and the study's
statistics. A robot runs without them."""


def missing_sim_extras() -> list[str]:
    """The modules of :data:`SIM_EXTRAS` that cannot be imported here (none looked at)."""
    from importlib.util import find_spec

    missing = []
    for name in SIM_EXTRAS:
        if name in sys.modules:
            installed = sys.modules[name] is not None
        else:
            try:
                installed = find_spec(name) is not None
            except (ImportError, ValueError):
                installed = False
        if not installed:
            missing.append(name)
    return missing


def needs_sim_extras(what: str, missing: list[str]) -> str:
    """The one line a command that needs the simulator's extras says without them."""
    return (
        f"{what} needs the simulator's extras ({', '.join(missing)} not installed):"
        " pip install 'dms[sim]'"
    )


class SimExtrasMissing(DmsError):
    """A command needs :data:`SIM_EXTRAS` and they are not installed."""

    def __init__(self, missing: list[str]) -> None:
        super().__init__(needs_sim_extras("this command", missing))
        self.missing = missing


def _sim() -> typer.Typer:
    missing = missing_sim_extras()
    if missing:  # said before a study runs for minutes and fails at its statistics
        raise SimExtrasMissing(missing)
    from sim.cli import app as sim_app

    return sim_app


def _record() -> typer.Typer:
    from sim.record_cli import record_app

    return record_app


def _secure() -> typer.Typer:
    from dms.secure_cli import app as secure_app

    return secure_app


def _fleet() -> typer.Typer:
    from dms.fleet_cli import app as fleet_app

    return fleet_app


SUB_APPS = (
    SubApp("rules", "Check and evaluate DMSL rule files.", _rules),
    SubApp("users", "List, show, export and erase user profiles.", _users),
    SubApp("db", "Database schema migrations.", lambda: db_app),
    SubApp("sessions", "Each real session's Table 4 metrics.", _sessions),
    SubApp("agenda", "Per-user events and reminders.", _agenda),
    SubApp("motivation", "The motivational model.", _motivation),
    SubApp("behavior", "Behavior files: check, draw, step, run.", _behavior),
    SubApp("sim", "Simulated sessions, studies and long-term runs.", _sim),
    SubApp("secure", "Mutual TLS and access control per role.", _secure),
    SubApp(
        "record",
        "Record a robot's keys into MCAP; dms record info|play FILE describes or plays one.",
        _record,
        own_help=True,
    ),
    SubApp("fleet", "The robots of a fleet: status.", _fleet),
)


app.command("router")(router_command)
app.command("foxglove")(foxglove_command)
app.command("ros2")(ros2_command)
app.command("reachy")(reachy_command)
app.command("view")(view_command)
app.command("studio")(studio_command)
app.command("face")(face_command)
use_studio_robot(_simulated_robot)  # the studio's trials drive the simulated Mini
app.command("topics")(topics_command)
app.command("echo")(echo_command)
app.command("state")(state_command)
app.command("request")(request_command)


@app.command()
def schema(
    directory: Annotated[Path, typer.Argument(help="Where to write the JSON Schemas.")],
) -> None:
    """Write a JSON Schema for every public message into DIRECTORY."""
    from dms.kernel.messages import write_schemas

    for path in write_schemas(directory):
        typer.echo(str(path))


def _setting(help_text: str, default: str, env: str) -> str:
    """The help of a ``dms run`` flag whose value may also come from the TOML file or
    the environment (the flag wins; docs/configuration.md)."""
    return f"{help_text} Default: {default}; environment: {env}."


@app.command()
def run(
    config: Annotated[
        Path | None,
        typer.Option(envvar="DMS_CONFIG", help="TOML configuration file.", show_default=False),
    ] = None,
    robot_id: Annotated[
        str | None,
        typer.Option("--robot-id", help=_setting("Robot id.", "mini", "DMS_ROBOT_ID")),
    ] = None,
    db: Annotated[
        str | None,
        typer.Option(
            help=_setting(
                "SQLAlchemy database URL or SQLite file.", "the user's data folder", "DMS_DB"
            )
        ),
    ] = None,
    listen: Annotated[
        list[str] | None,
        typer.Option(
            help=_setting("Zenoh endpoint to listen on.", "tcp/127.0.0.1:7447", "DMS_ZENOH__LISTEN")
        ),
    ] = None,
    connect: Annotated[
        list[str] | None,
        typer.Option(help=_setting("Zenoh endpoint to connect to.", "none", "DMS_ZENOH__CONNECT")),
    ] = None,
    zenoh_config: Annotated[
        Path | None,
        typer.Option(
            "--zenoh-config",
            help=_setting("Zenoh JSON5 configuration file.", "none", "DMS_ZENOH__CONFIG_FILE"),
        ),
    ] = None,
    robot: Annotated[
        Literal["sim", "zenoh"] | None,
        typer.Option(
            help=_setting(
                "The robot: sim (the simulated Mini, in-process) or zenoh (a real one).",
                "sim",
                "DMS_ROBOT",
            )
        ),
    ] = None,
    seed: Annotated[
        int | None,
        typer.Option(help=_setting("Seed of the random generator.", "random", "DMS_SEED")),
    ] = None,
    log_level: Annotated[
        Literal["debug", "info", "warning", "error"] | None,
        typer.Option(help=_setting("The least severe log line written.", "info", "DMS_LOG_LEVEL")),
    ] = None,
    log_format: Annotated[
        Literal["text", "json"] | None,
        typer.Option(
            help=_setting(
                "Log lines on stderr as text or as JSON objects.", "text", "DMS_LOG_FORMAT"
            )
        ),
    ] = None,
    visitor: Annotated[
        str | None,
        typer.Option(
            help="Run a simulated visitor (a persona name) beside it.", show_default=False
        ),
    ] = None,
    quiet: Annotated[bool, typer.Option(help="Do not print decisions.")] = False,
) -> None:
    """Run the daemon until SIGINT or SIGTERM (SIGHUP reloads the rules and behaviors).

    A setting comes from its flag, else its DMS_* variable, else the TOML, else its default.
    """
    gc.disable()  # until ready (run_daemon turns it back on there), or a refusal before
    try:
        from dms.config import load_config
        from dms.daemon import run_daemon

        settings = load_config(
            config,
            robot_id=robot_id,
            db=db,
            listen=listen,
            connect=connect,
            zenoh_config=zenoh_config,
            robot=robot,
            seed=seed,
            log_level=log_level,
            log_format=log_format,
        )
        if visitor is not None:
            _check_persona(visitor)  # before the daemon says it is ready
        code = run_daemon(
            settings,
            visitor=visitor,
            print_decisions=not quiet,
            sim_robot=_simulated_robot,
            start_visitor=_start_visitor,
        )
    finally:
        gc.enable()
    raise typer.Exit(code)


def _check_persona(persona: str) -> None:
    """Refuse a persona that does not exist or does not load (one line, exit 1)."""
    from sim.persona import load_persona

    load_persona(persona)


def _start_visitor(persona: str, settings: Settings) -> Callable[[], None]:
    """A simulated visitor beside the daemon (``dms run --visitor``); returns ``stop()``."""
    from sim.visitor import start_visitor

    return start_visitor(persona, settings)


INTERRUPTED = 128 + signal.SIGINT
"""The exit code after Ctrl-C (130), as a shell reports a program that SIGINT ended."""


def _leave_at_once(_signum: int, _frame: FrameType | None) -> None:
    """Ctrl-C before the command takes SIGINT over (``dms run`` does once its daemon is
    built): leave now and quietly. Nothing is served yet, and what is half-written is a
    database transaction that rolls back; unwinding instead could wait forever on a
    store's thread that was started and not yet owned by anything that stops it."""
    os._exit(INTERRUPTED)


def main(argv: list[str] | None = None) -> int:
    """Entry point of the console script; returns the exit code."""
    previous = signal.signal(signal.SIGINT, _leave_at_once)
    try:
        return _run_app(argv)
    finally:
        signal.signal(signal.SIGINT, previous)  # for a caller in the same process (tests)


def _command(argv: list[str] | None) -> str:
    """``dms sim study`` of ``dms sim study --sessions 3``: the command, for a message."""
    words = (argv if argv is not None else sys.argv[1:])[:2]
    return " ".join(["dms", *(word for word in words if not word.startswith("-"))])


def _run_app(argv: list[str] | None) -> int:
    try:
        result = app(args=argv, standalone_mode=False)
    except typer.Exit as done:
        return int(done.exit_code or 0)
    except typer.Abort:
        print("dms: aborted", file=sys.stderr)
        return INTERRUPTED
    except typer.TyperException as error:
        show = getattr(error, "show", None)
        if callable(show):
            show()  # usage errors print the usage line and the one-line message
        else:
            print(f"dms: {error}", file=sys.stderr)
        return int(getattr(error, "exit_code", 2) or 2)
    except SimExtrasMissing as error:
        print(f"dms: {needs_sim_extras(_command(argv), error.missing)}", file=sys.stderr)
        return 1
    except DmsError as error:
        print(f"dms: {error}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return INTERRUPTED
    except ModuleNotFoundError as error:  # a plot (dms motivation plot) without matplotlib
        top = (error.name or "").split(".")[0]
        if top not in SIM_EXTRAS:
            raise
        print(f"dms: {needs_sim_extras(_command(argv), [top])}", file=sys.stderr)
        return 1
    except OSError as error:
        print(f"dms: {error}", file=sys.stderr)
        return 1
    return result if isinstance(result, int) else 0


if __name__ == "__main__":
    sys.exit(main())
