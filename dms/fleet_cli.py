"""``dms router`` and ``dms fleet status``: the commands of a fleet (docs/fleet.md).

A care home runs one Zenoh router (or two), every daemon connects to it with
``--connect``, and all share one PostgreSQL database. The router is Zenoh's own
(:class:`dms.bus.ZenohRouter`); ``fleet status`` asks the router's network which
daemons are alive and what each is doing.
"""

from __future__ import annotations

import json
import signal
import threading
from typing import Annotated, Any

import typer

from dms.kernel import keys
from dms.kernel.cli_options import ConnectOption, ZenohConfigOption

app = typer.Typer(no_args_is_help=True, help="See and manage a fleet of robots.")


def router(
    listen: Annotated[
        list[str] | None,
        typer.Option(
            help="Endpoint to listen on (default tcp/127.0.0.1:7447).", show_default=False
        ),
    ] = None,
    zenoh_config: ZenohConfigOption = None,
) -> None:
    """Run a Zenoh router for a fleet until SIGINT or SIGTERM."""
    from dms.bus import DEFAULT_LISTEN, ZenohRouter, make_router_config

    endpoints = list(listen or ([] if zenoh_config else DEFAULT_LISTEN))
    stop = threading.Event()
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: stop.set())
    running = ZenohRouter(make_router_config(endpoints, zenoh_config))
    try:
        where = ", ".join(endpoints) or f"the endpoints of {zenoh_config}"
        typer.echo(f"dms router {running.zid} listening on {where}", err=True)
        stop.wait()
    finally:
        running.close()


def _state_row(robot: str, replies: list[tuple[bool, Any]]) -> dict[str, Any]:
    state = next((body for ok, body in replies if ok and isinstance(body, dict)), None)
    if state is None:
        return {"robot": robot, "error": "no reply to dms/state"}
    activity = state.get("activity") or {}
    user = state.get("user") or {}
    return {
        "robot": robot,
        "activity": activity.get("name"),
        "state": activity.get("state") or None,
        "user": user.get("id"),
        "mode": state.get("mode"),
        "robot_link": state.get("robot_link"),
        "time": state.get("time"),
    }


@app.command()
def status(
    connect: ConnectOption = None,
    zenoh_config: ZenohConfigOption = None,
    as_json: Annotated[bool, typer.Option("--json", help="One JSON object per robot.")] = False,
    timeout: Annotated[float, typer.Option(help="Seconds to wait for replies.", min=0.1)] = 2.0,
) -> None:
    """The robots alive (their ``alive/dms`` token), with activity, user and mode."""
    from dms.bus import ZenohClient, make_client_config

    config = make_client_config(list(connect or []), zenoh_config)
    with ZenohClient("fleet", config) as client:
        robots = client.alive_robots(timeout)
        rows = [
            _state_row(
                robot,
                client.query_absolute(keys.absolute(robot, keys.DMS_STATE), timeout_s=timeout),
            )
            for robot in robots
        ]
    if as_json:
        for row in rows:
            typer.echo(json.dumps(row))
        return
    if not rows:
        typer.echo("no robot alive", err=True)
        return
    from rich.console import Console
    from rich.table import Table

    table = Table("robot", "activity", "state", "user", "mode", "robot link")
    for row in rows:
        table.add_row(
            row["robot"],
            row.get("activity") or "-",
            row.get("state") or "-",
            row.get("user") or "-",
            row.get("mode") or row.get("error", "-"),
            row.get("robot_link") or "-",
        )
    Console().print(table)
