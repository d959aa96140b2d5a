"""The studio's "Take the robot's pose": a Reachy Mini posed by hand, then recorded.

When the studio is connected to a daemon whose robot is a Reachy Mini (``dms reachy``),
the page may ask the bridge, over Zenoh, to turn the head's gravity compensation on:
the designer moves the head by hand, and Record takes the joints the robot reports on
``robot/joints`` as the bridge maps them (``hip``, ``neck``, ``head``). Leaving the mode
asks for it off, and the robot holds where the hand left it. Every ask for on is a
lease the page renews while the mode lasts, so a closed tab never leaves the robot
limp. Only the Reachy bridge answers on :data:`KEY`; with no answer the page keeps the
mode off and says why.
"""

from __future__ import annotations

from typing import Any

from starlette.concurrency import run_in_threadpool
from starlette.requests import Request

from dms.studio.bodies import json_object
from dms.studio.errors import StudioError
from dms.studio.link import DaemonLink

KEY = "reachy/by_hand"
"""The bridge's queryable (``dms_reachy.by_hand.KEY``, in the bridge's own environment)."""
LEASE_S = 10.0
"""How long one ask keeps compensation on; the page renews it every third of this."""
ASK_TIMEOUT_S = 5.0
"""The bridge answers once its control thread switched the motors (within 3 s)."""
MAX_BODY = 1024


class HandPose:
    """The page's two calls, passed to the daemon's robot through the studio's link."""

    def __init__(self, link: DaemonLink | None) -> None:
        self.link = link

    async def state(self, _request: Request) -> dict[str, Any]:
        """Whether the daemon's robot can be posed by hand, and whether it is now."""
        return await run_in_threadpool(self.ask, None)

    async def switch(self, request: Request) -> dict[str, Any]:
        """``{"on": true}`` (or a renewal) or ``{"on": false}``."""
        data = await json_object(request, MAX_BODY, '{"on": true} or {"on": false}')
        on = data.get("on")
        if not isinstance(on, bool):
            raise StudioError('on: true or false, as in {"on": true}')
        return await run_in_threadpool(self.ask, on)

    def ask(self, on: bool | None) -> dict[str, Any]:
        """One ask to the bridge: its reply, or why there is none as a StudioError."""
        if self.link is None:
            raise StudioError("no daemon: start the studio with --connect ENDPOINT", 409)
        payload = None if on is None else {"on": on, "lease_s": LEASE_S}
        replies = self.link.client.query(KEY, payload, ASK_TIMEOUT_S)
        if not replies:
            raise StudioError(
                "the daemon's robot is not a Reachy Mini driven by `dms reachy` "
                "(nobody answered to pose it by hand)",
                409,
            )
        ok, reply = replies[0]
        if not ok:
            error = reply.get("error") if isinstance(reply, dict) else reply
            raise StudioError(f"the Reachy Mini bridge refused: {error}", 409)
        if not isinstance(reply, dict) or not isinstance(reply.get("by_hand"), bool):
            raise StudioError(f"the Reachy Mini bridge answered {reply!r}", 502)
        return {
            "by_hand": reply["by_hand"],
            "lease_s": reply.get("lease_s"),
            "renew_s": LEASE_S / 3,
        }
