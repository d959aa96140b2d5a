"""``dms studio``: serve the behavior studio until Ctrl-C, on loopback unless given TLS
files (:mod:`dms.viewer.tls`).

It prints a URL carrying the token the API asks for (as Jupyter does): open it, and
the page keeps the token. The robot a trial drives is wired by the composition root
(``dms/cli.py`` passes the simulated Mini), as for ``dms behavior step``. With
``--connect`` the studio also reaches a running daemon: its robot's joints for Record,
the frames it sees, and trying a behavior on its robot.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from dms.kernel.cli_options import RobotOption
from dms.kernel.errors import ConfigError
from dms.viewer.cli import AllowHostOption, PortOption, TlsCertOption, TlsKeyOption

if TYPE_CHECKING:
    from dms.studio.link import DaemonLink
    from dms.studio.trial import RobotFactory

DEFAULT_PORT = 8090

_robot_factory: list[RobotFactory] = []


def use_robot(factory: RobotFactory) -> None:
    """Wire the robot a trial drives (the composition root passes the simulated Mini)."""
    _robot_factory[:] = [factory]


def studio_command(
    folder: Annotated[
        Path | None,
        typer.Option(
            "--folder",
            help="The behaviors folder to edit.",
            show_default="the shipped behaviors",
        ),
    ] = None,
    port: PortOption = DEFAULT_PORT,
    host: Annotated[
        str,
        typer.Option(
            help="Address to serve on; it writes files: another than loopback needs "
            "--tls-cert and --tls-key."
        ),
    ] = "127.0.0.1",
    tls_cert: TlsCertOption = None,
    tls_key: TlsKeyOption = None,
    allow_host: AllowHostOption = None,
    rules: Annotated[
        list[Path] | None,
        typer.Option(
            "--rules",
            help="A DMSL rules file the rules pane edits (repeat for several).",
            show_default="the *.dmsl files of the folder",
        ),
    ] = None,
    connect: Annotated[
        list[str] | None,
        typer.Option(
            "--connect",
            help="A running daemon's Zenoh endpoint: try on its robot, record its joints.",
            show_default="no daemon: the simulated Mini only",
        ),
    ] = None,
    zenoh_config: Annotated[
        Path | None,
        typer.Option(help="A Zenoh config file (a secured bus: the admin role's)."),
    ] = None,
    robot: RobotOption = "mini",
) -> None:
    """Build, try and save behaviors with the mouse, in a web page.

    A palette of the blocks, the state machine drawn as boxes and arrows, the selected
    state's parameters checked as you type, and a trial on the simulated Mini that lights
    each state in turn. Saving keeps the file's comments and key order.
    """
    from activities.library import BEHAVIORS_DIR
    from dms.studio.app import Studio, create_app
    from dms.studio.folder import Folder
    from dms.studio.rules import rules_files
    from dms.viewer.auth import new_token
    from dms.viewer.cli import bind, page_url
    from dms.viewer.server import serve
    from dms.viewer.tls import server_context

    if not _robot_factory:
        raise ConfigError("no robot wired: run the studio through `dms studio`")
    directory = (folder or BEHAVIORS_DIR).resolve()
    if not directory.is_dir():
        raise ConfigError(f"--folder {directory}: not a directory")
    tls = server_context(tls_cert, tls_key)
    sock = bind(host, port, "studio", tls is not None)
    link: DaemonLink | None = None
    try:
        link = _connect(connect or [], zenoh_config, robot)
        address = sock.getsockname()
        token = new_token()
        url = f"{page_url(tls is not None, host, address[1])}/?token={token}"
        studio = Studio(
            Folder(directory, BEHAVIORS_DIR),
            _robot_factory[0],
            rules_files(directory, rules or []),
            link,
        )
        app = create_app(studio, token, address[1], host, tuple(allow_host or ()))
        daemon = f", robot {robot}'s daemon" if link is not None else ""
        ready = f"dms: studio on {url} (editing {directory}{daemon}); Ctrl-C stops"
        serve(app, sock, ready, on_exit=lambda: None, tls=tls)
    finally:
        sock.close()
        if link is not None:
            link.close()


def _connect(connect: list[str], zenoh_config: Path | None, robot: str) -> DaemonLink | None:
    """The link to a daemon, when one is named; None: the simulated Mini only."""
    if not connect and zenoh_config is None:
        return None
    from dms.bus import ZenohClient, make_client_config
    from dms.kernel.keys import ROBOT_ID_RE
    from dms.studio.link import DaemonLink

    if not ROBOT_ID_RE.fullmatch(robot):
        raise ConfigError(f"--robot {robot!r}: lower-case letters, digits, _ and -")
    return DaemonLink(ZenohClient(robot, make_client_config(connect, zenoh_config)))
