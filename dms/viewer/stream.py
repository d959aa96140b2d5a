"""A page's server-sent events: a first snapshot, then each change, bounded per page.

The viewer and the face page stream the same way: a source gives a listener its first
data when it attaches and calls it from its own thread with each event (an empty name:
the stream ends, the server stops). Each page's queue is bounded; one that lags more
than ``queue_limit`` events behind is cut off, and the browser reconnects to a fresh
snapshot. A comment every :data:`KEEPALIVE_S` keeps proxies from closing a quiet stream.
"""

from __future__ import annotations

import asyncio
import json
from collections.abc import AsyncIterator, Callable
from contextlib import suppress
from typing import Any

from starlette.responses import StreamingResponse

KEEPALIVE_S = 15.0

Listener = Callable[[str, dict[str, Any]], None]
_Event = tuple[str, dict[str, Any]] | None


def sse(name: str, data: Any) -> str:
    """One server-sent event (ValueError for data that is not plain JSON)."""
    return f"event: {name}\ndata: {json.dumps(data, separators=(',', ':'), allow_nan=False)}\n\n"


def event_stream(
    attach: Callable[[Listener], dict[str, Any] | None],
    detach: Callable[[Listener], None],
    queue_limit: int,
    full: str = "too many pages open",
) -> StreamingResponse:
    """The response streaming a source's events to one page: ``attach`` returns its first
    data (None: no room for another page, said in a ``full`` event, and the page does not
    reconnect); ``detach`` when the page goes."""
    loop = asyncio.get_running_loop()
    pending: asyncio.Queue[_Event] = asyncio.Queue()
    cut = False

    def put(event: _Event) -> None:
        nonlocal cut
        if cut:
            return
        if pending.qsize() >= queue_limit:
            cut, event = True, None
        pending.put_nowait(event)

    def listener(name: str, data: dict[str, Any]) -> None:
        with suppress(RuntimeError):  # the server is stopping: its loop is closed
            loop.call_soon_threadsafe(put, (name, data) if name else None)

    async def stream() -> AsyncIterator[str]:
        first = attach(listener)
        if first is None:
            yield sse("full", {"error": full})
            return
        try:
            yield "retry: 1000\n" + sse("snapshot", first)
            while True:
                try:
                    event = await asyncio.wait_for(pending.get(), KEEPALIVE_S)
                except TimeoutError:
                    yield ": keepalive\n\n"
                    continue
                if event is None:
                    return
                try:
                    yield sse(*event)
                except ValueError:  # not plain JSON (the sources drop such payloads)
                    continue
        finally:
            detach(listener)

    return StreamingResponse(
        stream(),
        media_type="text/event-stream",
        headers={"Cache-Control": "no-store", "X-Accel-Buffering": "no"},
    )
