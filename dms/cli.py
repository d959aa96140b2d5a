"""The ``dms`` console script: one typer app with a sub-app per package.

``main`` runs it so that every failure a person can cause (a bad flag, a bad file,
a database that cannot be opened) ends as one ``dms: ...`` line on stderr and a
non-zero exit, never a traceback. ``dms --version`` prints the installed version;
``dms --install-completion`` installs typer's shell completion (bash, zsh, fish).
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Literal

import typer

from activities.cli import app as behavior_app
from activities.cli import use_robot
from agenda.cli import app as agenda_app
from dms.fleet_cli import app as fleet_app
from dms.fleet_cli import router as router_command
from dms.foxglove_cli import foxglove as foxglove_command
from dms.kernel.errors import DmsError
from dms.kernel.ports import RobotPort
from dms.operator_cli import echo_command, state_command, topics_command
from dms.rules_cli import app as rules_app
from dms.secure_cli import app as secure_app
from dms.viewer.cli import view_command
from memory.cli import DbOption, first_line, upgrade_profiles
from memory.cli import app as users_app
from memory.sessions_cli import app as sessions_app
from motivation.cli import app as motivation_app
from sim.cli import app as sim_app
from sim.cli import record_app

if TYPE_CHECKING:
    from dms.config import Settings

app = typer.Typer(
    name="dms",
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
def upgrade(db: DbOption = None) -> None:
    """Bring the database's schema (profiles and agenda) to the newest version.

    Each package owns its migrations; the composition root runs them all, in order.
    """
    from sqlalchemy.exc import SQLAlchemyError

    from agenda import migrations as agenda_migrations
    from memory.db import default_url
    from memory.errors import ProfileError

    url = db or default_url()
    for line in upgrade_profiles(url):
        typer.echo(line)
    try:
        agenda_migrations.upgrade(url)
    except (SQLAlchemyError, ImportError, OSError) as error:
        raise ProfileError(f"cannot upgrade the agenda in {url}: {first_line(error)}") from None
    typer.echo("agenda: at head")


def _simulated_robot(seed: int) -> RobotPort:
    """The robot ``dms behavior step|run`` drives: the simulated Mini (imported when used)."""
    from sim.robot import SimRobot

    return SimRobot(rng_seed=seed)


use_robot(_simulated_robot)
app.add_typer(rules_app, name="rules", help="Check and evaluate DMSL rule files.")
app.add_typer(users_app, name="users", help="List, show, export and erase user profiles.")
app.add_typer(db_app, name="db", help="Database schema migrations.")
app.add_typer(sessions_app, name="sessions", help="Each real session's Table 4 metrics.")
app.add_typer(agenda_app, name="agenda", help="Per-user events and reminders.")
app.add_typer(motivation_app, name="motivation", help="The motivational model.")
app.add_typer(behavior_app, name="behavior", help="Behavior files: check, draw, step, run.")
app.add_typer(sim_app, name="sim", help="Simulated sessions, studies and long-term runs.")
app.add_typer(secure_app, name="secure", help="Mutual TLS and access control per role.")
app.add_typer(record_app, name="record")
app.add_typer(fleet_app, name="fleet", help="The robots of a fleet: status.")
app.command("router")(router_command)
app.command("foxglove")(foxglove_command)
app.command("view")(view_command)
app.command("topics")(topics_command)
app.command("echo")(echo_command)
app.command("state")(state_command)


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
    raise typer.Exit(
        run_daemon(
            settings,
            visitor=visitor,
            print_decisions=not quiet,
            sim_robot=_simulated_robot,
            start_visitor=_start_visitor,
        )
    )


def _start_visitor(persona: str, settings: Settings) -> Callable[[], None]:
    """A simulated visitor beside the daemon (``dms run --visitor``); returns ``stop()``."""
    from sim.visitor import start_visitor

    return start_visitor(persona, settings)


def main(argv: list[str] | None = None) -> int:
    """Entry point of the console script; returns the exit code."""
    try:
        result = app(args=argv, standalone_mode=False)
    except typer.Exit as done:
        return int(done.exit_code or 0)
    except typer.Abort:
        print("dms: aborted", file=sys.stderr)
        return 130
    except typer.TyperException as error:
        show = getattr(error, "show", None)
        if callable(show):
            show()  # usage errors print the usage line and the one-line message
        else:
            print(f"dms: {error}", file=sys.stderr)
        return int(getattr(error, "exit_code", 2) or 2)
    except DmsError as error:
        print(f"dms: {error}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 130
    except OSError as error:
        print(f"dms: {error}", file=sys.stderr)
        return 1
    return result if isinstance(result, int) else 0


if __name__ == "__main__":
    sys.exit(main())
