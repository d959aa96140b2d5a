"""The face's web side: the page, its static files, an event stream and a small JSON API.

Every request passes :func:`dms.face.access.guards` first (foreign ``Host`` 421, a write
from a foreign ``Origin`` 403, no token 403; the static files need no token). Then:

- ``GET /`` the page; ``GET /events`` server-sent events (:mod:`dms.face.feed`): a
  ``snapshot``, then each change; ``GET /api/snapshot`` the same snapshot as JSON;
- ``POST /api/screen`` ``{choice}``: a tap on the tablet (``perception/screen``);
- ``POST /api/say`` ``{text}``: a typed answer (``perception/speech``, confidence 1);
- ``POST /api/touch`` ``{part, kind}``: a touch on the body (``perception/touch``);
- ``POST /api/here`` ``{user_id, consent}``: the person sits down (``perception/user``);
  409 for someone new without ``consent: true``; ``POST /api/leave``: they go;
- ``GET /api/people``: ask the daemon again whom it knows (the answer comes as an event);
- ``POST /api/voice`` (a WAV body): push-to-talk, transcribed here and sent as
  ``perception/speech`` with its confidence; the reply says what was heard.

A malformed request is a 400 with one line naming what was wrong.
"""

from __future__ import annotations

import json
from collections.abc import Awaitable, Callable
from importlib import resources
from pathlib import Path
from typing import Any

from pydantic import ValidationError
from starlette.applications import Starlette
from starlette.concurrency import run_in_threadpool
from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse, Response
from starlette.routing import Mount, Route
from starlette.staticfiles import StaticFiles

from dms.face.access import guards
from dms.face.feed import FaceFeed
from dms.face.link import FaceLink
from dms.face.voice import MAX_BYTES, Transcriber, VoiceError
from dms.kernel.ids import InvalidIdentifier
from dms.viewer.stream import event_stream

STATIC = Path(str(resources.files("dms.face") / "static"))
QUEUE_LIMIT = 2000
"""Events a page may lag behind before it is cut off (it reconnects to a fresh snapshot)."""
MAX_BODY = 16_384
"""The largest JSON request: a tap or a typed answer is a few hundred bytes."""


class BadRequest(Exception):
    """A request the API refuses: its message and status go back to the page."""

    def __init__(self, message: str, status: int = 400) -> None:
        super().__init__(message)
        self.status = status


Handler = Callable[[Request], Awaitable[Any]]


def api(handler: Handler) -> Callable[[Request], Awaitable[Response]]:
    async def endpoint(request: Request) -> Response:
        try:
            return JSONResponse(await handler(request))
        except BadRequest as error:
            return JSONResponse({"error": str(error)}, error.status)

    return endpoint


async def fields(request: Request) -> dict[str, Any]:
    raw = await request.body()
    if len(raw) > MAX_BODY:
        raise BadRequest("request too large", 413)
    try:
        data = json.loads(raw or b"{}")
    except ValueError:
        raise BadRequest("the request is not JSON") from None
    if not isinstance(data, dict):
        raise BadRequest("the request is a JSON object")
    return data


def text_field(data: dict[str, Any], name: str) -> str:
    value = data.get(name)
    if not isinstance(value, str) or not value.strip():
        raise BadRequest(f"{name}: a non-empty text")
    return value.strip()


def one_line(error: ValidationError) -> str:
    first = error.errors()[0]
    where = ".".join(str(part) for part in first["loc"]) or "message"
    return f"{where}: {first['msg']}"


class Face:
    """The API's handlers over the feed, the bus link and the transcriber."""

    def __init__(self, feed: FaceFeed, link: FaceLink, transcriber: Transcriber | None) -> None:
        self.feed = feed
        self.link = link
        self.transcriber = transcriber

    async def screen(self, request: Request) -> Any:
        choice = text_field(await fields(request), "choice")
        try:
            self.link.screen(choice)
        except ValidationError as error:
            raise BadRequest(one_line(error)) from None
        return {"sent": "perception/screen", "choice": choice}

    async def say(self, request: Request) -> Any:
        text = text_field(await fields(request), "text")
        try:
            self.link.speech(text, 1.0)
        except ValidationError as error:
            raise BadRequest(one_line(error)) from None
        return {"sent": "perception/speech", "text": text}

    async def touch(self, request: Request) -> Any:
        data = await fields(request)
        try:
            self.link.touch(str(data.get("part")), str(data.get("kind", "tap")))
        except ValidationError as error:
            raise BadRequest(one_line(error)) from None
        return {"sent": "perception/touch"}

    async def here(self, request: Request) -> Any:
        data = await fields(request)
        user_id = text_field(data, "user_id")
        try:
            user = self.link.arrive(user_id, data.get("consent") is True)
        except InvalidIdentifier as error:
            raise BadRequest(f"user_id: {error}") from None
        except PermissionError as error:
            raise BadRequest(str(error), 409) from None
        return {"sent": "perception/user", "user_id": user}

    async def leave(self, _request: Request) -> Any:
        self.link.leave()
        return {"sent": "perception/user", "present": False}

    async def people(self, _request: Request) -> Any:
        self.link.refresh_people()
        return {"asked": "users/*"}

    async def voice(self, request: Request) -> Any:
        if self.transcriber is None:
            raise BadRequest(self.feed.voice_missing or "voice input is off", 503)
        chunks: list[bytes] = []
        size = 0
        async for chunk in request.stream():
            size += len(chunk)
            if size > MAX_BYTES:
                raise BadRequest("the recording is too long", 413)
            chunks.append(chunk)
        try:
            heard = await run_in_threadpool(self.transcriber.transcribe, b"".join(chunks))
        except VoiceError as error:
            raise BadRequest(str(error)) from None
        self.feed.heard(heard.text, heard.confidence)
        if heard.text:
            self.link.speech(heard.text, heard.confidence)
        return {"text": heard.text, "confidence": heard.confidence, "sent": bool(heard.text)}


def create_app(
    face: Face,
    token: str,
    port: int,
    host: str = "127.0.0.1",
    allow_hosts: tuple[str, ...] = (),
) -> Starlette:
    """The app serving ``face`` on ``host:port`` behind the token and the host guard."""
    feed = face.feed

    async def index(_request: Request) -> Response:
        return FileResponse(STATIC / "index.html", headers={"Cache-Control": "no-store"})

    async def snapshot(_request: Request) -> Response:
        return JSONResponse(feed.snapshot())

    async def events(_request: Request) -> Response:
        return event_stream(
            feed.attach, feed.detach, QUEUE_LIMIT, "too many pages open on this face"
        )

    return Starlette(
        routes=[
            Route("/", index),
            Route("/events", events),
            Route("/api/snapshot", snapshot),
            Route("/api/screen", api(face.screen), methods=["POST"]),
            Route("/api/say", api(face.say), methods=["POST"]),
            Route("/api/touch", api(face.touch), methods=["POST"]),
            Route("/api/here", api(face.here), methods=["POST"]),
            Route("/api/leave", api(face.leave), methods=["POST"]),
            Route("/api/people", api(face.people)),
            Route("/api/voice", api(face.voice), methods=["POST"]),
            Mount("/static", StaticFiles(directory=STATIC), name="static"),
        ],
        middleware=guards(token, port, host, allow_hosts),
    )
