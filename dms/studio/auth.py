"""The studio's token: a request without it is refused, as Jupyter's server does.

The studio writes files, so loopback alone is not enough: any local program, or a page
of another site that got past the host guard, could call it. The command prints a URL
carrying ``?token=...``; the page keeps the token and sends it with every API call in
the ``X-Studio-Token`` header. The static files (script, style, layout library) hold
nothing private and are served without it.
"""

from __future__ import annotations

import hmac
import secrets
from urllib.parse import parse_qs

from starlette.responses import PlainTextResponse
from starlette.types import ASGIApp, Receive, Scope, Send

HEADER = b"x-studio-token"
PUBLIC_PREFIX = "/static/"
REFUSED = (
    "403 Forbidden: missing or wrong token. Open the URL that `dms studio` printed "
    "when it started: it carries ?token=...\n"
)


def new_token() -> str:
    """A fresh token, 32 random bytes as URL-safe text."""
    return secrets.token_urlsafe(32)


class TokenGuard:
    """ASGI middleware: 403 for a request that carries neither the header nor
    ``?token=`` with the studio's token (the static files aside)."""

    def __init__(self, app: ASGIApp, token: str) -> None:
        self.app = app
        self.token = token.encode()

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http" or str(scope["path"]).startswith(PUBLIC_PREFIX):
            await self.app(scope, receive, send)
            return
        if not self._carries_token(scope):
            response = PlainTextResponse(REFUSED, 403)
            await response(scope, receive, send)
            return
        await self.app(scope, receive, send)

    def _carries_token(self, scope: Scope) -> bool:
        given = [value for name, value in scope["headers"] if name == HEADER]
        query = parse_qs(scope.get("query_string", b"").decode("latin-1"))
        given.extend(value.encode() for value in query.get("token", []))
        return any(hmac.compare_digest(value, self.token) for value in given)
