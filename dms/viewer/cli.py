"""``dms view``: serve the live page of the daemons on the bus until Ctrl-C.

It prints a URL carrying the token the page asks for (:mod:`dms.viewer.auth`), as
``dms studio`` does: open it, and the browser keeps the token in a cookie.
"""

from __future__ import annotations

import socket
from pathlib import Path
from typing import Annotated

import typer

from dms.kernel.cli_options import ConnectOption, ZenohConfigOption
from dms.kernel.errors import ConfigError
from dms.kernel.keys import ROBOT_ID_RE
from dms.viewer.tls import refuse_clear_text

DEFAULT_PORT = 8080

TLS_CERT_HELP = "A PEM certificate: serve HTTPS (needed for a --host other than loopback)."
TLS_KEY_HELP = "The PEM private key of --tls-cert, without a passphrase."

# The options every page (the viewer, the studio, the face) spells alike; each page
# says in its own --host's help why another address than loopback needs TLS.
PortOption = Annotated[int, typer.Option(min=0, max=65535, help="HTTP port (0: any free port).")]
TlsCertOption = Annotated[Path | None, typer.Option("--tls-cert", help=TLS_CERT_HELP)]
TlsKeyOption = Annotated[Path | None, typer.Option("--tls-key", help=TLS_KEY_HELP)]
AllowHostOption = Annotated[
    list[str] | None,
    typer.Option(
        "--allow-host",
        help="Another name the page is opened by (with --host 0.0.0.0: the machine's name).",
        show_default="loopback names, the --host address",
    ),
]


def check_robot_ids(robots: list[str]) -> list[str]:
    for robot in robots:
        if not ROBOT_ID_RE.fullmatch(robot):
            raise ConfigError(f"--robot: {robot!r} does not match [a-z0-9_-]+")
    return robots


def bind(host: str, port: int, page: str, tls: bool) -> socket.socket:
    """The listening socket, bound before anything else starts: a port in use is one line.

    Without ``tls`` only a loopback address is bound (:func:`~dms.viewer.tls.refuse_clear_text`),
    checked on what ``host`` resolves to: a name may stand for the machine's LAN address.
    """
    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE)
    except socket.gaierror as error:
        raise ConfigError(f"--host {host}: {error.strerror}") from None
    family, kind, proto, _name, address = infos[0]
    if not tls:
        refuse_clear_text(page, host, str(address[0]))
    sock = socket.socket(family, kind, proto)
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind(address)
        sock.listen(128)
    except OSError as error:
        sock.close()
        raise ConfigError(f"cannot serve on {host}:{port}: {error.strerror or error}") from None
    return sock


def view_command(
    connect: ConnectOption = None,
    zenoh_config: ZenohConfigOption = None,
    port: PortOption = DEFAULT_PORT,
    host: Annotated[
        str,
        typer.Option(
            help="Address to serve on; another than loopback needs --tls-cert and "
            "--tls-key (the token would cross the network in the clear)."
        ),
    ] = "127.0.0.1",
    tls_cert: TlsCertOption = None,
    tls_key: TlsKeyOption = None,
    allow_host: AllowHostOption = None,
    robot: Annotated[
        list[str] | None,
        typer.Option(
            "--robot",
            "--robot-id",
            help="Show only this robot (repeat for more).",
            show_default="every robot on the bus",
        ),
    ] = None,
) -> None:
    """Serve a live web page of the robots on the bus.

    The page shows each robot's activity with its state machine, the session, the drives
    over the last hour, the decisions with their why, the inputs, the agenda and the errors.
    """
    from dms.bus import ZenohClient, make_client_config
    from dms.viewer.app import create_app
    from dms.viewer.auth import new_token
    from dms.viewer.model import LiveModel
    from dms.viewer.server import serve
    from dms.viewer.source import BusSource
    from dms.viewer.tls import server_context
    from motivation.config import MotivationConfig

    robots = check_robot_ids(list(robot or []))
    config = make_client_config(connect or (), zenoh_config)  # a bad file fails before the port
    tls = server_context(tls_cert, tls_key)
    sock = bind(host, port, "viewer", tls is not None)
    try:
        defaults = {name: drive.threshold for name, drive in MotivationConfig().drives.items()}
        model = LiveModel(robots, default_thresholds=defaults)
        with ZenohClient(robots[0] if robots else "mini", config) as client:
            source = BusSource(client, model, robots)
            source.start()
            try:
                address = sock.getsockname()
                token = new_token()
                url = f"{page_url(tls is not None, host, address[1])}/?token={token}"
                watched = ", ".join(robots) if robots else "every robot on the bus"
                ready = f"dms: viewer on {url} ({watched}); Ctrl-C stops"
                app = create_app(model, token, address[1], host, tuple(allow_host or ()))
                serve(app, sock, ready, on_exit=model.end_streams, tls=tls)
            finally:
                source.close()
    finally:
        sock.close()


def page_url(tls: bool, host: str, port: int) -> str:
    """``http(s)://HOST:PORT`` of a page, for the line that says where it serves."""
    shown = f"[{host}]" if ":" in host else host
    return f"{'https' if tls else 'http'}://{shown}:{port}"
