"""``dms ros2``: run the ROS 2 bridge (the ``ros2/`` distribution) in its own environment.

The ROS 2 wheels pin lark-parser 0.12, which installs the same ``lark`` module as the
lark 1.x the rule language needs, so the bridge cannot share the daemon's environment.
It gets one of its own, ``.venv-ros2`` beside the checkout (the folder holding
``ros2/``), made with the daemon's Python and pip, and talks to the daemon over Zenoh
only. The environment is made or brought up to date when ``ros2/pyproject.toml`` is
newer than its stamp; then this process becomes the bridge (``exec``).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path
from typing import Annotated

import typer

from dms.kernel import keys
from dms.kernel.cli_options import ConnectOption, RobotOption, ZenohConfigOption
from dms.kernel.errors import ConfigError

CHECKOUT = Path(__file__).resolve().parents[1]
"""The folder holding ``dms/`` and, in a checkout, ``ros2/``."""
SOURCE = CHECKOUT / "ros2"
VENV = CHECKOUT / ".venv-ros2"
STAMP_NAME = ".installed-stamp"


def bridge_python(venv: Path = VENV) -> Path:
    return venv / "bin" / "python"


def prepare(venv: Path = VENV, source: Path = SOURCE, echo: bool = True) -> Path:
    """Make (or bring up to date) the bridge's environment; return its Python.

    Raises ConfigError, with pip's last lines, when it cannot be made (no checkout, no
    network and no cache, a Python the ROS 2 wheels are not built for)."""
    project = source / "pyproject.toml"
    if not project.is_file():
        raise ConfigError(
            f"dms ros2 needs the source checkout: {project} is missing "
            "(the bridge is installed from ros2/ beside dms/)"
        )
    stamp = venv / STAMP_NAME
    python = bridge_python(venv)
    if python.exists() and stamp.exists() and stamp.stat().st_mtime >= project.stat().st_mtime:
        return python
    if echo:
        typer.echo(f"dms ros2: preparing {venv} (pip install -e {source})", err=True)
    steps = [
        [sys.executable, "-m", "venv", str(venv)],
        [str(python), "-m", "pip", "install", "--quiet", "-e", str(source)],
    ]
    for step in steps:
        done = subprocess.run(step, capture_output=True, text=True, check=False)
        if done.returncode != 0:
            tail = " | ".join((done.stderr or done.stdout).strip().splitlines()[-3:])
            raise ConfigError(f"cannot prepare {venv}: {' '.join(step[:4])}: {tail}")
    stamp.touch()
    return python


def ros2(
    robot: RobotOption = "mini",
    connect: ConnectOption = None,
    zenoh_config: ZenohConfigOption = None,
    unconfigured: Annotated[
        bool,
        typer.Option(help="Leave the node for a lifecycle manager to configure and activate."),
    ] = False,
    only_prepare: Annotated[
        bool,
        typer.Option("--prepare", help="Only make or update the bridge's environment, then exit."),
    ] = False,
) -> None:
    """Bridge a robot's keys to ROS 2 and back (node dms_bridge in /robots/<id>) until
    SIGINT or SIGTERM; the bridge runs in its own environment, .venv-ros2 beside the
    checkout, made on first use (docs/ros2.md)."""
    if not keys.ROBOT_ID_RE.match(robot):
        raise ConfigError(f"--robot {robot!r}: lower-case letters, digits, _ and - only")
    python = prepare()
    if only_prepare:
        typer.echo(str(python))
        return
    argv = [str(python), "-m", "dms_ros2", "--robot", robot]
    for endpoint in connect or []:
        argv += ["--connect", endpoint]
    if zenoh_config is not None:
        argv += ["--zenoh-config", str(zenoh_config)]
    if unconfigured:
        argv.append("--unconfigured")
    sys.stdout.flush()
    sys.stderr.flush()
    os.execv(argv[0], argv)
