"""The pages' token (``dms view``, ``dms studio``): a request without it is refused, as
Jupyter's server does.

Loopback alone is not enough: any local user's program could read the viewer's page
(the residents' ids and state, or what the role certificates it was started with
protect) or call the studio, which writes files. The command makes a token when it
starts and prints a URL carrying ``?token=...``. A request carries it in that query, in
the header ``X-<PAGE>-Token`` (scripts; the studio's page sends it with every call), or
in the cookie set when the URL with the token was first opened, which the browser then
sends with the page's own requests (the viewer's event stream). The static files
(script, style, chart and layout libraries) hold nothing private and are served
without it.
"""

from __future__ import annotations

import hmac
import secrets
from http.cookies import CookieError, SimpleCookie
from urllib.parse import parse_qs

from starlette.datastructures import MutableHeaders
from starlette.responses import PlainTextResponse
from starlette.types import ASGIApp, Message, Receive, Scope, Send

PUBLIC_PREFIX = "/static/"


def new_token() -> str:
    """A fresh token, 32 random bytes as URL-safe text."""
    return secrets.token_urlsafe(32)


def header_name(page: str) -> str:
    """The header a script sends the token in: ``X-Viewer-Token``, ``X-Studio-Token``."""
    return f"X-{page.capitalize()}-Token"


def cookie_name(page: str, port: int) -> str:
    """The cookie holding the token. Browsers keep cookies per host name, not per port:
    the port in the name keeps two pages on one machine (a viewer on 8080, the studio on
    8090, a second viewer) from overwriting each other's."""
    return f"dms-{page}-{port}"


def refusal(command: str) -> str:
    return (
        f"403 Forbidden: missing or wrong token. Open the URL that `dms {command}` printed "
        "when it started: it carries ?token=...\n"
    )


class TokenGuard:
    """ASGI middleware: 403 for a request that carries the page's token neither in
    ``?token=``, nor in its header, nor in its cookie (the static files aside). A
    request that carried it in the query gets the cookie, so that the page's own later
    requests need not carry it."""

    def __init__(self, app: ASGIApp, token: str, page: str, command: str, port: int) -> None:
        """``page``: ``viewer`` or ``studio`` (the header's and cookie's name);
        ``command``: what prints the URL (``view``, ``studio``), named in the refusal."""
        self.app = app
        self.token = token.encode()
        self.header = header_name(page).lower().encode()
        self.cookie = cookie_name(page, port)
        self.refused = refusal(command)

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        kind = scope["type"]
        if kind not in ("http", "websocket") or str(scope["path"]).startswith(PUBLIC_PREFIX):
            await self.app(scope, receive, send)  # the server's lifespan; the static files
            return
        in_query = self._in_query(scope)
        if not (in_query or self._in_header_or_cookie(scope)):
            if kind == "websocket":  # closed before it is accepted: the client sees a 403
                await send({"type": "websocket.close", "code": 1008})
                return
            response = PlainTextResponse(self.refused, 403)
            await response(scope, receive, send)
            return
        if not in_query or kind == "websocket":
            await self.app(scope, receive, send)
            return
        secure = "; Secure" if scope.get("scheme") == "https" else ""
        cookie = f"{self.cookie}={self.token.decode()}; Path=/; HttpOnly; SameSite=Strict{secure}"

        async def send_with_cookie(message: Message) -> None:
            if message["type"] == "http.response.start":
                MutableHeaders(scope=message).append("Set-Cookie", cookie)
            await send(message)

        await self.app(scope, receive, send_with_cookie)

    def _matches(self, value: bytes) -> bool:
        return hmac.compare_digest(value, self.token)

    def _in_query(self, scope: Scope) -> bool:
        query = parse_qs(scope.get("query_string", b"").decode("latin-1"))
        return any(self._matches(value.encode()) for value in query.get("token", []))

    def _in_header_or_cookie(self, scope: Scope) -> bool:
        for name, value in scope["headers"]:
            if name == self.header and self._matches(value):
                return True
            if name == b"cookie" and self._in_cookie(value.decode("latin-1")):
                return True
        return False

    def _in_cookie(self, header: str) -> bool:
        jar: SimpleCookie = SimpleCookie()
        try:
            jar.load(header)
        except CookieError:
            return False
        morsel = jar.get(self.cookie)
        return morsel is not None and self._matches(morsel.value.encode())
