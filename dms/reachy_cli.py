"""``dms reachy``: drive a Reachy Mini as the daemon's robot, from its own environment.

Pollen Robotics' SDK (``reachy-mini``, with its MuJoCo simulator) pins its own pydantic,
numpy, starlette and pip floors and builds PyGObject against Debian's cairo and
GObject headers: installed beside the daemon it would move the daemon's dependencies.
The bridge is therefore a distribution of its own, ``reachy/`` in the checkout, installed
into ``.venv-reachy`` beside it with the daemon's Python, made or brought up to date
when ``reachy/pyproject.toml`` is newer than its stamp; then this process becomes the
bridge (``exec``). It reaches the daemon over Zenoh only (docs/reachy.md).
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from dms.bridge_env import become_bridge, check_robot, prepare_environment
from dms.bridge_env import bridge_python as environment_python
from dms.kernel.cli_options import (
    ConnectOption,
    PrepareOption,
    RobotOption,
    ZenohConfigOption,
)
from dms.kernel.errors import ConfigError

CHECKOUT = Path(__file__).resolve().parents[1]
"""The folder holding ``dms/`` and, in a checkout, ``reachy/``."""
SOURCE = CHECKOUT / "reachy"
VENV = CHECKOUT / ".venv-reachy"
SYSTEM_PACKAGES = (
    "libcairo2-dev libgirepository1.0-dev gir1.2-gstreamer-1.0 gir1.2-gst-plugins-base-1.0"
    " espeak-ng"
)
"""Debian's packages the SDK needs (PyGObject builds against the first two, the SDK's
daemon loads GStreamer's bindings, Gst, GstApp and GstPbutils) and the bridge's voice."""


def bridge_python(venv: Path = VENV) -> Path:
    return environment_python(venv)


def prepare(venv: Path = VENV, source: Path = SOURCE, echo: bool = True) -> Path:
    """Make (or bring up to date) the bridge's environment; return its Python
    (:func:`dms.bridge_env.prepare_environment`)."""
    return prepare_environment(
        "reachy", venv, source, echo, f"on Debian: apt-get install {SYSTEM_PACKAGES}"
    )


def reachy(
    robot: RobotOption = "mini",
    connect: ConnectOption = None,
    zenoh_config: ZenohConfigOption = None,
    host: Annotated[str, typer.Option(help="The Reachy Mini daemon's host.")] = "localhost",
    port: Annotated[int, typer.Option(help="The Reachy Mini daemon's port.")] = 8000,
    media: Annotated[
        bool,
        typer.Option(help="Speak through the robot's speaker (espeak-ng); off: print speech."),
    ] = False,
    faces: Annotated[
        bool,
        typer.Option(
            help="Publish the face the robot's camera tracks as perception/user "
            "(off: a perception module publishes it; docs/reachy.md)."
        ),
    ] = False,
    only_prepare: PrepareOption = False,
) -> None:
    """Drive a Reachy Mini (real or simulated) as the robot of a daemon run with
    ``--robot zenoh``, until SIGINT or SIGTERM; the bridge runs in its own environment,
    .venv-reachy beside the checkout, made on first use (docs/reachy.md)."""
    check_robot(robot)
    if not 0 < port < 65536:
        raise ConfigError(f"--port {port}: a TCP port, 1 to 65535")
    python = prepare()
    if only_prepare:
        typer.echo(str(python))
        return
    extra = ["--host", host, "--port", str(port)]
    extra += ["--media"] if media else []
    extra += ["--faces"] if faces else []
    become_bridge(python, "dms_reachy", robot, connect, zenoh_config, extra)
