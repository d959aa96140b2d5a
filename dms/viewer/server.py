"""uvicorn on a socket the viewer bound itself, saying on stderr when it serves."""

from __future__ import annotations

import socket
import ssl
import sys
from collections.abc import Callable
from types import FrameType

import uvicorn
from starlette.applications import Starlette

GRACE_S = 2
"""How long open pages are given to close when the viewer stops."""


class _Server(uvicorn.Server):
    def __init__(
        self, config: uvicorn.Config, ready_line: str, on_exit: Callable[[], None]
    ) -> None:
        super().__init__(config)
        self._ready_line = ready_line
        self._on_exit = on_exit

    def handle_exit(self, sig: int, frame: FrameType | None) -> None:
        """Stop, without uvicorn raising the signal again afterwards: SIGINT and SIGTERM
        are how the viewer is meant to stop, so it exits 0. Open pages' streams end now,
        so that nothing waits for them."""
        super().handle_exit(sig, frame)
        self._captured_signals.clear()
        self._on_exit()

    async def startup(self, sockets: list[socket.socket] | None = None) -> None:
        await super().startup(sockets)
        if not self.should_exit:  # a script (or a test) waits for this line
            print(self._ready_line, file=sys.stderr, flush=True)


def serve(
    app: Starlette,
    sock: socket.socket,
    ready_line: str,
    on_exit: Callable[[], None],
    tls: ssl.SSLContext | None = None,
) -> None:
    """Serve ``app`` on ``sock`` until SIGINT or SIGTERM; ``on_exit`` is called then.
    With ``tls`` (:func:`dms.viewer.tls.server_context`) it serves HTTPS."""
    config = uvicorn.Config(
        app, log_level="warning", access_log=False, timeout_graceful_shutdown=GRACE_S
    )
    config.load()
    # uvicorn builds a context only from file names, with no minimum version; the one
    # checked at the start is set in its place (uvicorn does not load a loaded config).
    config.ssl = tls
    _Server(config, ready_line, on_exit).run(sockets=[sock])
