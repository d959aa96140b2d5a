"""``dms face``: serve the robot's face and tablet for a person in front of it, until
Ctrl-C, on loopback unless given TLS files (:mod:`dms.viewer.tls`).

It prints a URL carrying the page's token, as the studio does: open it on the laptop or
the tablet the person uses (with ``--host`` and TLS, from another machine).
"""

from __future__ import annotations

from typing import Annotated

import typer

from dms.kernel.cli_options import ConnectOption, RobotOption, ZenohConfigOption
from dms.kernel.errors import ConfigError
from dms.viewer.cli import AllowHostOption, PortOption, TlsCertOption, TlsKeyOption

DEFAULT_PORT = 8070
LANGUAGE_RE = r"[A-Za-z]{2,3}(-[A-Za-z0-9]{2,8})*"


def face_command(
    connect: ConnectOption = None,
    zenoh_config: ZenohConfigOption = None,
    robot: RobotOption = "mini",
    port: PortOption = DEFAULT_PORT,
    host: Annotated[
        str,
        typer.Option(
            help="Address to serve on; another than loopback (a tablet on the network) "
            "needs --tls-cert and --tls-key."
        ),
    ] = "127.0.0.1",
    tls_cert: TlsCertOption = None,
    tls_key: TlsKeyOption = None,
    allow_host: AllowHostOption = None,
    language: Annotated[
        str,
        typer.Option(
            help="The voice's language (BCP 47) for a person whose profile names none.",
        ),
    ] = "en",
) -> None:
    """Serve the robot's face and tablet as one page, for a person in front of it.

    Eyes that look where the robot looks, a mouth that moves as it speaks, its cheeks'
    colour, its voice with captions, and a tablet for menus and answers; taps, typed
    answers, touches and "I am here" / "I am leaving" go to the daemon as perception.
    """
    import re

    from dms.bus import ZenohClient, make_client_config
    from dms.face.access import new_token
    from dms.face.app import Face, create_app
    from dms.face.feed import FaceFeed
    from dms.face.link import FaceLink
    from dms.face.voice import Transcriber, unavailable
    from dms.kernel.keys import ROBOT_ID_RE
    from dms.viewer.cli import bind, page_url
    from dms.viewer.server import serve
    from dms.viewer.tls import server_context

    if not ROBOT_ID_RE.fullmatch(robot):
        raise ConfigError(f"--robot {robot!r}: lower-case letters, digits, _ and -")
    if not re.fullmatch(LANGUAGE_RE, language):
        raise ConfigError(f"--language {language!r}: a language tag such as en, es or en-GB")
    config = make_client_config(connect or (), zenoh_config)  # a bad file fails before the port
    tls = server_context(tls_cert, tls_key)
    sock = bind(host, port, "face", tls is not None)
    try:
        missing = unavailable()
        feed = FaceFeed(robot, voice=missing, language=language)
        link = FaceLink(ZenohClient(robot, config), feed)
        try:
            link.start()
            address = sock.getsockname()
            token = new_token()
            url = f"{page_url(tls is not None, host, address[1])}/?token={token}"
            face = Face(feed, link, None if missing else Transcriber())
            app = create_app(face, token, address[1], host, tuple(allow_host or ()))
            voice = "" if missing is None else f"; {missing}"
            ready = f"dms: face on {url} (robot {robot}{voice}); Ctrl-C stops"
            serve(app, sock, ready, on_exit=feed.end_streams, tls=tls)
        finally:
            link.close()
    finally:
        sock.close()
