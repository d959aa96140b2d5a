"""``dms secure``: the files of a secured deployment (mutual TLS, access control).

The work is in :mod:`dms.secure`, imported only when a ``secure`` command runs (it
loads ``cryptography``, which no other command needs); this turns flags into calls and
lists what was written, so that an operator sees where each role's files are.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from dms.kernel.cli_options import RobotOption

app = typer.Typer(no_args_is_help=True)


@app.command()
def init(
    directory: Annotated[Path, typer.Argument(help="Where to write the CA, keys and configs.")],
    robot_id: RobotOption,
    listen: Annotated[
        str | None,
        typer.Option(
            help="The daemon's endpoint, tls/HOST:PORT (default tls/127.0.0.1:7447); "
            "the other roles connect to it."
        ),
    ] = None,
    force: Annotated[bool, typer.Option(help="Replace files already in DIRECTORY.")] = False,
) -> None:
    """A CA and, per role (dms, perception, robot, app, admin, face), a key, certificate and
    Zenoh config with mutual TLS and access control. See docs/security.md."""
    from dms.secure import DEFAULT_LISTEN
    from dms.secure import init as write

    for path in write(directory, robot_id, listen or DEFAULT_LISTEN, force=force):
        typer.echo(str(path))
    typer.echo(
        f"run the daemon with: dms run --zenoh-config {directory / 'dms.json5'}; keep ca.key "
        "offline once the roles are deployed",
        err=True,
    )


@app.command()
def renew(
    directory: Annotated[Path, typer.Argument(help="A folder written by `dms secure init`.")],
    role: Annotated[str, typer.Argument(help="dms, perception, robot, app, admin or face.")],
) -> None:
    """A new key and certificate for ROLE from the same CA (a leaked key, an expiry)."""
    from dms.secure import renew as write

    for path in write(directory, role):
        typer.echo(str(path))
