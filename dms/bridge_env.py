"""The environment of a bridge that cannot share the daemon's (``dms ros2``, ``dms reachy``).

A bridge whose libraries pin other versions than the daemon's (the ROS 2 wheels' lark,
Reachy Mini's SDK and its pydantic, numpy and PyGObject) is a distribution of its own
beside ``dms/`` in the checkout. It is installed into a virtual environment of its own,
made with the daemon's Python, and made again when its ``pyproject.toml`` is newer than
the environment's stamp; the bridge then reaches the daemon over Zenoh only.
"""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import NoReturn

import typer

from dms.kernel import keys
from dms.kernel.errors import ConfigError

STAMP_NAME = ".installed-stamp"


def bridge_python(venv: Path) -> Path:
    """The Python of the bridge's environment ``venv``."""
    return venv / "bin" / "python"


def prepare_environment(command: str, venv: Path, source: Path, echo: bool, hint: str = "") -> Path:
    """Make (or bring up to date) ``venv`` with the distribution at ``source``; return its
    Python. ``command`` names the bridge in messages; ``hint``: what to do when pip fails.

    Raises ConfigError, with pip's last lines, when it cannot be made (no checkout, no
    network and no cache, a system package missing)."""
    project = source / "pyproject.toml"
    if not project.is_file():
        raise ConfigError(
            f"dms {command} needs the source checkout: {project} is missing "
            f"(the bridge is installed from {source.name}/ beside dms/)"
        )
    stamp = venv / STAMP_NAME
    python = bridge_python(venv)
    if python.exists() and stamp.exists() and stamp.stat().st_mtime >= project.stat().st_mtime:
        return python
    if echo:
        typer.echo(f"dms {command}: preparing {venv} (pip install -e {source})", err=True)
    steps = [
        [sys.executable, "-m", "venv", str(venv)],
        [str(python), "-m", "pip", "install", "--quiet", "-e", str(source)],
    ]
    for step in steps:
        done = subprocess.run(step, capture_output=True, text=True, check=False)
        if done.returncode != 0:
            tail = " | ".join((done.stderr or done.stdout).strip().splitlines()[-3:])
            more = f" ({hint})" if hint else ""
            raise ConfigError(f"cannot prepare {venv}: {' '.join(step[:4])}: {tail}{more}")
    stamp.touch()
    return python


def check_robot(robot: str) -> None:
    """Refuse a robot id the daemon could not have, before the environment is made."""
    if not keys.ROBOT_ID_RE.fullmatch(robot):
        raise ConfigError(f"--robot {robot!r}: lower-case letters, digits, _ and - only")


def become_bridge(
    python: Path,
    module: str,
    robot: str,
    connect: list[str] | None,
    zenoh_config: Path | None,
    extra: list[str],
    env: Mapping[str, str] | None = None,
) -> NoReturn:
    """Replace this process with the bridge ``module`` in its environment's ``python``, for
    ``robot``, with the daemon's Zenoh options and the bridge's own ``extra`` arguments;
    ``env``: the bridge's environment variables (this process's when None)."""
    argv = [str(python), "-m", module, "--robot", robot, *extra]
    for endpoint in connect or []:
        argv += ["--connect", endpoint]
    if zenoh_config is not None:
        argv += ["--zenoh-config", str(zenoh_config)]
    sys.stdout.flush()
    sys.stderr.flush()
    os.execve(argv[0], argv, dict(os.environ if env is None else env))
