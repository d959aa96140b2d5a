"""The studio's link to a running daemon (``dms studio --connect``), over Zenoh.

It keeps the last ``robot/joints`` the robot reported (the Record button takes them) and
the last state of a try on the daemon (``dms/try``, lit on the canvas), and asks the
daemon on its ``studio/try`` queryable to start a try (the whole behavior or one state,
running or state by state), step, answer, stop it or name the frames it sees. A refusal
(a session is open, not the ``admin`` role on a secured bus) is the reply's one line,
shown as it is.
"""

from __future__ import annotations

import threading
from typing import Any

from dms.bus import ZenohClient
from dms.kernel import keys
from dms.studio.daemon_try import TRY_KEY, TRY_STATE_KEY
from dms.studio.errors import StudioError

QUERY_TIMEOUT_S = 5.0


class DaemonLink:
    """A Zenoh client of one robot's daemon, for the studio."""

    def __init__(self, client: ZenohClient) -> None:
        self.client = client
        self.lock = threading.Lock()
        self.joints: dict[str, float] | None = None
        self.try_states: list[dict[str, Any]] = []
        """The try's states as published, since the last start."""
        client.subscribe(keys.ROBOT_JOINTS, self._on_joints)
        client.subscribe(TRY_STATE_KEY, self._on_try)

    def _on_joints(self, _key: str, payload: Any) -> None:
        positions = payload.get("positions") if isinstance(payload, dict) else None
        if isinstance(positions, dict):
            with self.lock:
                self.joints = {str(k): round(float(v), 3) for k, v in positions.items()}

    def _on_try(self, _key: str, payload: Any) -> None:
        if isinstance(payload, dict):
            with self.lock:
                self.try_states.append(payload)

    def ask(self, payload: dict[str, Any]) -> dict[str, Any]:
        """One query on the daemon's try queryable: its reply, or the refusal as an error."""
        replies = self.client.query(TRY_KEY, payload, QUERY_TIMEOUT_S)
        if not replies:
            raise StudioError(
                "the daemon did not answer: is `dms run` up, and may this role try "
                "(admin on a secured bus)?",
                503,
            )
        ok, body = replies[0]
        if not ok:
            error = body.get("error") if isinstance(body, dict) else body
            raise StudioError(f"the daemon refused: {error}", 409)
        return body if isinstance(body, dict) else {"reply": body}

    def start(
        self, doc: dict[str, Any], state: str | None = None, step: bool = False
    ) -> dict[str, Any]:
        """Start a try of ``doc`` (of its ``state`` alone), stopping at each state if ``step``."""
        with self.lock:
            self.try_states = []
        asked: dict[str, Any] = {"op": "start", "doc": doc, "step": step}
        if state:
            asked["state"] = state
        return self.ask(asked)

    def states(self, since: int) -> list[dict[str, Any]]:
        """The try's states published from the ``since``-th on."""
        with self.lock:
            return list(self.try_states[since:])

    def robot_joints(self) -> dict[str, float]:
        with self.lock:
            joints = self.joints
        if joints is None:
            raise StudioError("no robot/joints from the daemon's robot yet", 503)
        return dict(joints)

    def frames(self) -> list[str]:
        return [str(frame) for frame in self.ask({"op": "frames"}).get("frames", [])]

    def close(self) -> None:
        self.client.close()
