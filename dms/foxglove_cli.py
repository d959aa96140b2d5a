"""``dms foxglove``: serve robots' keys live to Foxglove (:mod:`dms.foxglove_bridge`)."""

from __future__ import annotations

import signal
import threading
from typing import Annotated

import typer

from dms.kernel import keys
from dms.kernel.cli_options import ConnectOption, ZenohConfigOption
from dms.kernel.errors import ConfigError


def foxglove(
    connect: ConnectOption = None,
    zenoh_config: ZenohConfigOption = None,
    port: Annotated[
        int, typer.Option(help="WebSocket port for Foxglove.", min=0, max=65535)
    ] = 8765,
    host: Annotated[
        str, typer.Option(help="Address to serve on (loopback unless you open it).")
    ] = "127.0.0.1",
    robot: Annotated[
        str,
        typer.Option("--robot", help="The robot whose keys to bridge; '*' for every robot."),
    ] = "mini",
    robot_id: Annotated[
        str | None, typer.Option("--robot-id", hidden=True, help="The former name of --robot.")
    ] = None,
    allow_origin: Annotated[
        list[str] | None,
        typer.Option(
            "--allow-origin",
            help="A web origin allowed to connect (https://app.foxglove.dev); "
            "native clients and loopback pages always are.",
        ),
    ] = None,
    personal_data: Annotated[
        bool,
        typer.Option(
            "--personal-data",
            help="Also forward what the daemon's privacy settings hold back: speech, "
            "screen choices, user ids, free text.",
        ),
    ] = False,
) -> None:
    """Bridge robots' keys live to Foxglove (its WebSocket protocol, with JSON Schemas)
    until SIGINT or SIGTERM."""
    from dms.bus import ZenohClient, make_client_config
    from dms.foxglove_bridge import FoxgloveBridge

    robot_id = robot_id if robot_id is not None else robot
    if robot_id != "*" and not keys.ROBOT_ID_RE.fullmatch(robot_id):
        raise ConfigError(f"--robot {robot_id!r}: lower-case letters, digits, _ and - only")
    config = make_client_config(list(connect or []), zenoh_config)
    stop = threading.Event()
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: stop.set())
    try:  # the port first: a port in use is said before any network wait
        bridge = FoxgloveBridge(
            host, port, allow_origin or (), personal_data, every_robot=robot_id == "*"
        )
    except (RuntimeError, OSError) as error:
        raise ConfigError(f"--port {port}: {' '.join(str(error).split())}") from None
    try:
        if robot_id != "*":
            bridge.advertise(robot_id)
        with ZenohClient("foxglove", config) as client:
            client.subscribe_raw(f"robots/{robot_id}/**", bridge.on_sample)
            typer.echo(
                f"dms foxglove: ws://{host}:{bridge.port} (Foxglove: Open connection, "
                "Foxglove WebSocket)",
                err=True,
            )
            stop.wait()
    finally:
        bridge.stop()
