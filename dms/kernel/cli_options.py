"""The command-line options that several commands share, each defined once.

A command that reaches the bus, names a robot, opens the database or prints JSON takes
the same flag, spelt, defaulted and explained the same way as every other. The options
are ``typer`` annotations, used as a parameter's type (``db: DbOption = None``); they
live in the kernel so that the command line of every package (memory's, the agenda's,
the composition root's) may use them.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

DEFAULT_ENDPOINT = "tcp/127.0.0.1:7447"
"""Where a command connects without ``--connect``: the daemon's default listen endpoint."""

ConnectOption = Annotated[
    list[str] | None,
    typer.Option(
        "--connect",
        help="Zenoh endpoint of a daemon or router (repeat for more).",
        show_default=DEFAULT_ENDPOINT,
    ),
]
"""Zenoh endpoints to connect to; None: :data:`DEFAULT_ENDPOINT`."""

ZenohConfigOption = Annotated[
    Path | None,
    typer.Option("--zenoh-config", help="Zenoh JSON5 configuration file.", show_default=False),
]

RobotOption = Annotated[
    str,
    typer.Option("--robot", "--robot-id", envvar="DMS_ROBOT_ID", help="Robot id."),
]
"""The robot a command is about, as the daemon names itself (its ``DMS_ROBOT_ID``)."""

DbOption = Annotated[
    str | None,
    typer.Option(
        "--db",
        envvar="DMS_DB",
        help="SQLAlchemy database URL or SQLite file (default: the daemon's).",
        show_default=False,
    ),
]

JsonOption = Annotated[bool, typer.Option("--json", help="Print JSON.")]

PrepareOption = Annotated[
    bool,
    typer.Option("--prepare", help="Only make or update the bridge's environment, then exit."),
]
"""A bridge's ``--prepare`` (``dms ros2``, ``dms reachy``)."""
