"""Who may use the face page: the pages' token and the viewer's Host and Origin guard.

The page publishes perception into the daemon (a tap, a touch, who is here), so, as for
the studio, loopback alone is not enough: every request but the static files carries the
token (``?token=``) that ``dms face`` prints with its URL. This module is the face's one
use of those guards, so that it follows them wherever they move.
"""

from __future__ import annotations

from starlette.middleware import Middleware

from dms.viewer.auth import TokenGuard, new_token
from dms.viewer.guard import WILDCARDS, HostGuard, allowed_hosts

__all__ = ["guards", "new_token"]


def guards(token: str, port: int, host: str, allow_hosts: tuple[str, ...]) -> list[Middleware]:
    """The middleware, outermost first: a foreign ``Host`` is 421, a write from a foreign
    ``Origin`` 403, then a request without the token 403."""
    return [
        Middleware(
            HostGuard,
            hosts=allowed_hosts(host, port, allow_hosts),
            port=port,
            any_address=host in WILDCARDS,
        ),
        Middleware(TokenGuard, token=token, page="face", command="face", port=port),
    ]
