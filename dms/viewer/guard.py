"""Which requests the viewer answers: those sent to the address it serves.

The page has no login; what keeps other web sites out is the browser's same-origin
rule. A site can get around it by DNS rebinding: its own name, resolved again to
127.0.0.1, makes the browser send the site's requests to the viewer as the site's own.
Those requests carry the site's name in their ``Host`` header: a request whose host is
not one the viewer serves under gets ``421 Misdirected Request``. A request that could
change something (any method but GET and HEAD) from another site's page carries that
site's ``Origin``: it gets ``403 Forbidden``.
"""

from __future__ import annotations

import ipaddress
from collections.abc import Iterable

from starlette.responses import PlainTextResponse
from starlette.types import ASGIApp, Receive, Scope, Send

LOOPBACK_NAMES = ("127.0.0.1", "localhost", "[::1]")
WILDCARDS = ("0.0.0.0", "::", "")
SAFE_METHODS = frozenset({"GET", "HEAD"})


def allowed_hosts(host: str, port: int, extra: Iterable[str] = ()) -> frozenset[str]:
    """The ``Host`` values the viewer answers: each of the loopback names, ``host`` and
    ``extra`` with ``:port`` (and bare, on port 80, where browsers leave the port out)."""
    names = {*LOOPBACK_NAMES, *(_bracketed(name) for name in (host, *extra) if name)}
    out = {f"{name}:{port}".lower() for name in names}
    if port == 80:
        out |= {name.lower() for name in names}
    return frozenset(out)


def _bracketed(name: str) -> str:
    return f"[{name}]" if ":" in name and not name.startswith("[") else name


def _is_address(host: str, port: int) -> bool:
    """Whether ``host`` is an IP address with ``port``: a name that no DNS answer can
    point elsewhere."""
    name, given = host, ""
    if (not host.endswith("]") and host.count(":") == 1) or "]:" in host:
        name, _, given = host.rpartition(":")
    if given != str(port) and not (port == 80 and not given):
        return False
    try:
        ipaddress.ip_address(name.strip("[]"))
    except ValueError:
        return False
    return True


class HostGuard:
    """ASGI middleware: refuses a foreign ``Host`` (421) and a foreign ``Origin`` on a
    request that is not GET or HEAD (403).

    ``any_address``: the viewer serves on every interface (``--host 0.0.0.0``), so a
    request to any IP address of the machine is answered (an address cannot be rebound).
    """

    def __init__(
        self, app: ASGIApp, hosts: frozenset[str], port: int, any_address: bool = False
    ) -> None:
        self.app = app
        self.hosts = hosts
        self.port = port
        self.any_address = any_address

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        headers = {name: value for name, value in scope["headers"]}
        host = headers.get(b"host", b"").decode("latin-1").strip().lower()
        if not self._host_ok(host):
            response = PlainTextResponse("421 Misdirected Request: unknown host\n", 421)
            await response(scope, receive, send)
            return
        origin = headers.get(b"origin")
        if scope["method"] not in SAFE_METHODS and origin is not None:
            seen = origin.decode("latin-1").strip().lower()
            if seen != f"{scope.get('scheme', 'http')}://{host}":  # https when served with TLS
                response = PlainTextResponse("403 Forbidden: foreign origin\n", 403)
                await response(scope, receive, send)
                return
        await self.app(scope, receive, send)

    def _host_ok(self, host: str) -> bool:
        return host in self.hosts or (self.any_address and _is_address(host, self.port))
