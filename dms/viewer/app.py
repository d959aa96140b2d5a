"""The viewer's web side: the page, its static files and a server-sent event stream.

``GET /`` is the page, ``GET /static/...`` its script, style and chart library (shipped in
the package), ``GET /events`` the stream: one ``snapshot`` event with everything the
model holds, then each change as it happens: ``robot``, ``state``, ``decision``,
``decisions`` (the whole list, once a daemon's recent ones joined it), ``structure``,
``agenda``, ``body`` (the joints and the last aim, at most four times a second) and
``report`` (a ``dms/errors`` message; an event named
``error`` would be taken by the browser for the stream's own failure). ``GET
/api/snapshot`` is the snapshot as JSON (for scripts and tests). A page that falls too far
behind is cut off; its browser reconnects at once and starts again from a fresh snapshot.
When the viewer stops, :meth:`LiveModel.end_streams` ends every stream at once. Every
request goes through :class:`~dms.viewer.guard.HostGuard` first (DNS rebinding), then
:class:`~dms.viewer.auth.TokenGuard` (no token, 403: the page shows residents' ids and
what they said).
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from starlette.applications import Starlette
from starlette.middleware import Middleware
from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse, Response
from starlette.routing import Mount, Route
from starlette.staticfiles import StaticFiles

from dms.viewer.auth import TokenGuard
from dms.viewer.guard import WILDCARDS, HostGuard, allowed_hosts
from dms.viewer.model import LiveModel
from dms.viewer.stream import event_stream

STATIC = Path(str(resources.files("dms.viewer") / "static"))
QUEUE_LIMIT = 5000
"""Events a page may lag behind before it is cut off (it reconnects to a fresh snapshot)."""


def create_app(
    model: LiveModel,
    token: str,
    port: int,
    host: str = "127.0.0.1",
    allow_hosts: tuple[str, ...] = (),
) -> Starlette:
    """The app serving ``model`` on ``host:port`` (``0.0.0.0`` or ``::``: every interface,
    reached by any of its addresses or ``allow_hosts``' names) to whoever has ``token``."""

    async def index(_request: Request) -> Response:
        return FileResponse(STATIC / "index.html", headers={"Cache-Control": "no-store"})

    async def snapshot(_request: Request) -> Response:
        return JSONResponse(model.snapshot())

    async def events(_request: Request) -> Response:
        return event_stream(model.attach, model.detach, QUEUE_LIMIT)

    return Starlette(
        routes=[
            Route("/", index),
            Route("/events", events),
            Route("/api/snapshot", snapshot),
            Mount("/static", StaticFiles(directory=STATIC), name="static"),
        ],
        middleware=[
            Middleware(
                HostGuard,
                hosts=allowed_hosts(host, port, allow_hosts),
                port=port,
                any_address=host in WILDCARDS,
            ),
            Middleware(TokenGuard, token=token, page="viewer", command="view", port=port),
        ],
    )
