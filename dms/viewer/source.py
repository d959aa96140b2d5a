"""The viewer's side of the bus: subscriptions that feed :class:`LiveModel`, and a worker
thread for the queries it asks for (a query is never made from a Zenoh callback).

Per robot (or ``robots/*`` when none is named): the ``alive/**`` tokens, ``dms/state``,
``dms/decision``, ``dms/errors``, ``robot/joints`` (where the robot looks) and
``robot/command`` (of which only the ``aim`` channel is kept); ``dms/config`` (for the
drives' thresholds) and ``dms/decisions`` (what it decided before the viewer came) when a
daemon comes, ``dms/behavior`` when the activity changes,
and ``agenda/*`` when the user changes and every :data:`AGENDA_EVERY_S` seconds. An
agenda that the daemon does not serve (``[privacy] serve_profiles``, or the viewer's role in a
secured deployment) is shown with the daemon's reason. A payload over
:data:`~dms.viewer.bounds.MAX_READ_BYTES` is not parsed: the model is told its size.
"""

from __future__ import annotations

import json
import logging
import queue
import threading
import time
from collections.abc import Callable, Sequence
from typing import Any

from dms.bus import ZenohClient
from dms.kernel import keys
from dms.viewer.bounds import MAX_READ_BYTES
from dms.viewer.model import LiveModel, robot_of
from motivation.config import load_config

log = logging.getLogger(__name__)

CONFIG_KEY = "dms/config"
"""The daemon's settings, versions and files (the drives' thresholds are read from it)."""
DECISIONS_KEY = "dms/decisions"
"""The daemon's last decisions, asked for when it comes."""
AGENDA_EVERY_S = 30.0
QUERY_TIMEOUT_S = 3.0


class BusSource:
    """Feeds ``model`` from ``client`` until :meth:`close`."""

    def __init__(self, client: ZenohClient, model: LiveModel, robots: Sequence[str] = ()) -> None:
        self.client = client
        self.model = model
        self.robots = list(robots) or ["*"]
        self._jobs: queue.Queue[tuple[str, str] | None] = queue.Queue()
        self._worker = threading.Thread(target=self._work, name="dms-view-queries", daemon=True)
        self._agenda_read: dict[str, float] = {}

    def start(self) -> None:
        self.model.need = self.need
        self._worker.start()
        handlers = {
            keys.DMS_STATE: self.model.on_state,
            keys.DMS_DECISION: self.model.on_decision,
            keys.DMS_ERRORS: self.model.on_error,
            keys.ROBOT_JOINTS: self.model.on_joints,
            keys.ROBOT_COMMAND: self.model.on_command,
        }
        for robot in self.robots:
            for key, handler in handlers.items():
                self.client.subscribe_raw(
                    keys.absolute(robot, key), self._json(handler, self._oversized(key))
                )
            self.client.watch_tokens(
                keys.absolute(robot, keys.ALIVE_PREFIX + "**"), self.model.on_token
            )

    def _oversized(self, key: str) -> Callable[[str, int], None]:
        return lambda robot, size: self.model.on_oversized(robot, key, size)

    @staticmethod
    def _json(handler: Any, oversized: Callable[[str, int], None] | None = None) -> Any:
        def on_sample(key_expr: str, raw: bytes) -> None:
            robot = robot_of(key_expr)
            if robot is None:
                return
            if len(raw) > MAX_READ_BYTES:
                if oversized is not None:
                    oversized(robot, len(raw))
                return
            try:
                payload = json.loads(raw, parse_constant=_not_json)
            except (ValueError, RecursionError):
                return  # not a daemon's: the daemon publishes plain JSON only
            handler(robot, payload)

        return on_sample

    def need(self, robot: str, what: str) -> None:
        """Ask for a query (from any thread, without blocking)."""
        self._jobs.put((robot, what))

    def close(self) -> None:
        self._jobs.put(None)
        self._worker.join(timeout=2 * QUERY_TIMEOUT_S)

    # ------------------------------------------------------------------ the worker

    def _work(self) -> None:
        while True:
            try:
                job = self._jobs.get(timeout=self._until_agenda())
            except queue.Empty:
                job = ("", "agenda-poll")
            if job is None:
                return
            robot, what = job
            try:
                if what == "behavior":
                    self._read_behavior(robot)
                elif what == "config":
                    self._read_config(robot)
                elif what == "agenda":
                    self._read_agenda(robot)
                elif what == "decisions":
                    self._read_decisions(robot)
                else:
                    for alive in self.model.agenda_due():
                        self._read_agenda(alive)
            except Exception:  # one failed query must not end the worker
                log.exception("query %s for %s", what, robot)

    def _until_agenda(self) -> float:
        if not self._agenda_read:
            return AGENDA_EVERY_S
        oldest = min(self._agenda_read.values())
        return max(0.1, oldest + AGENDA_EVERY_S - time.monotonic())

    def _read_behavior(self, robot: str) -> None:
        replies = self._query(robot, keys.DMS_BEHAVIOR)
        state = next((body for ok, body in replies if ok and isinstance(body, dict)), None)
        if state is not None:
            self.model.set_structure(robot, state)
        else:
            why = _reason(replies[0][1]) if replies else "no reply to dms/behavior"
            self.model.set_structure(robot, {"error": why})

    def _read_config(self, robot: str) -> None:
        """The drives' thresholds from the daemon's settings (``dms/config``), as the
        motivation package reads them (its defaults under the file's overrides)."""
        replies = self._query(robot, CONFIG_KEY)
        body = next((body for ok, body in replies if ok and isinstance(body, dict)), None)
        settings = body.get("settings") if body is not None else None
        if not isinstance(settings, dict):
            return  # an older daemon: the page draws the shipped defaults, and says so
        try:
            config = load_config(settings.get("motivation") or {})
        except ValueError as error:
            log.warning("dms/config of %s: motivation settings not understood: %s", robot, error)
            return
        thresholds = {name: drive.threshold for name, drive in config.active_drives.items()}
        self.model.set_thresholds(robot, thresholds)

    def _read_decisions(self, robot: str) -> None:
        """The daemon's last decisions (an older daemon has none to give: nothing shown)."""
        replies = self._query(robot, DECISIONS_KEY)
        body = next((body for ok, body in replies if ok and isinstance(body, dict)), None)
        decisions = body.get("decisions") if body is not None else None
        if isinstance(decisions, list):
            self.model.set_recent(robot, decisions)

    def _read_agenda(self, robot: str) -> None:
        self._agenda_read[robot] = time.monotonic()
        replies = self._query(robot, keys.AGENDA_PREFIX + "*")
        if not replies:
            self.model.set_agenda(
                robot, {"error": "no reply (the daemon has no agenda, or is gone)"}
            )
            return
        ok, body = replies[0]
        if ok and isinstance(body, dict) and isinstance(body.get("items"), list):
            self.model.set_agenda(robot, {"items": body["items"]})
        else:
            self.model.set_agenda(robot, {"error": _reason(body)})

    def _query(self, robot: str, key: str) -> list[tuple[bool, Any]]:
        try:
            return self.client.query_absolute(keys.absolute(robot, key), timeout_s=QUERY_TIMEOUT_S)
        except ValueError:
            return [(False, {"error": "the reply is not JSON"})]


def _not_json(constant: str) -> Any:
    """``NaN`` and ``Infinity`` are Python's, not JSON's: such a payload is dropped."""
    raise ValueError(f"{constant} is not JSON")


def _reason(body: Any) -> str:
    if isinstance(body, dict) and isinstance(body.get("error"), str):
        return str(body["error"])
    return "the reply is not understood"
