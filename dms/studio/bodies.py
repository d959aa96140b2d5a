"""The JSON object a request to the studio carries, refused in one line when it is not."""

from __future__ import annotations

import json
from typing import Any

from starlette.requests import Request

from dms.studio.errors import StudioError

MAX_BODY = 2_000_000
"""The largest request body taken: a behavior is a few kilobytes."""


async def json_object(request: Request, limit: int = MAX_BODY, example: str = "") -> dict[str, Any]:
    """The request's body as a JSON object (an empty body is ``{}``); ``example`` shows
    what to send in the refusal."""
    raw = await request.body()
    if len(raw) > limit:
        raise StudioError("request too large", 413)
    try:
        data = json.loads(raw or b"{}")
    except ValueError:
        raise StudioError("the request is not JSON" + (f": {example}" if example else "")) from None
    if not isinstance(data, dict):
        raise StudioError("the request is a JSON object" + (f": {example}" if example else ""))
    return data
