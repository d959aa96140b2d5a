"""Trying a behavior from the studio on a running daemon's robot: the daemon's side.

The studio asks with a query on :data:`TRY_KEY` (a query, so that a refusal comes back
as one line in its reply); on a secured bus only the ``admin`` role may query it
(``dms.secure``). The daemon serves a try only when nobody is in a session: a person in
front of the robot is never interrupted by a test. A try runs the behavior the page
holds, saved or not, on the daemon's robot through its expression arbiter, ticked by the
daemon's loop after the controller, beside the robot's own idling; it is cancelled as
soon as a session opens. Each change of state is published on :data:`TRY_STATE_KEY` for
the page to light.

As on the simulated Mini (:mod:`dms.studio.trial`), a try may run one state alone (a
behavior of that state whose outcomes end it), and may go state by state as ``dms
behavior step`` does: it ticks until the state path changes or the behavior ends, then
holds still (the robot's last commands go on) until the next step.

Payloads: ``{"op": "start", "doc": {...}, "state": "PATH", "step": true}`` (``state`` and
``step`` optional), ``{"op": "step"}`` (on to the next state; a running try stops at
its next state from then on), ``{"op": "answer", "text": "..."}`` (words said,
``screen:CHOICE``, ``touch:PART``), ``{"op": "stop"}``, ``{"op": "frames"}`` (the frames
the daemon sees now, for the studio's frame picker).
"""

from __future__ import annotations

import json
import logging
import threading
from collections.abc import Callable
from datetime import datetime
from typing import TYPE_CHECKING, Any

from activities.activity import Activity
from activities.errors import BehaviorError
from activities.library import BehaviorLibrary
from activities.spec import check_references, parse_text
from activities.stepper import parse_input
from dms.kernel.errors import DmsError
from dms.studio.check import WHERE, document_text
from dms.studio.errors import StudioError
from dms.studio.trial import one_state

if TYPE_CHECKING:
    from dms.assembly import Stack

log = logging.getLogger(__name__)

TRY_KEY = "studio/try"
"""The queryable a studio asks on (relative to ``robots/<id>/``)."""
TRY_STATE_KEY = "dms/try"
"""Where the try's progress is published: under ``dms/`` so every watcher may read it."""
FRAME_PREFIXES = ("user", "face:", "object:")


class TryRefused(DmsError):
    """A try the daemon does not serve now; the message is the reply's one line."""


class DaemonTry:
    """The try running on the daemon, if any; its query handler and its tick."""

    def __init__(
        self,
        stack: Stack,
        lock: threading.Lock,
        publish: Callable[[str, Any], None],
        clock: Callable[[], datetime],
    ) -> None:
        """``lock`` is the daemon's (queries come on Zenoh's threads, ticks on the loop's);
        ``publish(key, payload)`` publishes under the robot; ``clock()`` is now."""
        self.stack = stack
        self.clock = clock
        self.lock = lock
        self.publish = publish
        self.activity: Activity | None = None
        self.behavior = ""
        self.stepping = False
        """Stop at each new state (``step``), as ``dms behavior step`` does."""
        self.paused = False
        """Holding still at a state until the next ``step``."""
        self._before = ""
        self._shown: tuple[str, str, bool] | None = None
        self._userdata: dict[str, Any] = {}
        """The userdata as last published, to say which keys changed."""

    # ---------------------------------------------------------------- the query

    def serve(self, _key: str, payload: bytes | None) -> tuple[bool, Any]:
        """One query: its reply, or an error reply with the reason (never raises)."""
        try:
            data = json.loads(payload or b"{}")
        except ValueError:
            return False, {"error": "the payload is not JSON"}
        if not isinstance(data, dict):
            return False, {"error": 'the payload is an object: {"op": "start", "doc": {...}}'}
        op = data.get("op")
        try:
            with self.lock:
                if op == "start":
                    return True, self._start(
                        data.get("doc"), data.get("state"), data.get("step") is True
                    )
                if op == "step":
                    return True, self._step()
                if op == "answer":
                    return True, self._answer(data.get("text"))
                if op == "stop":
                    return True, self._stop("stopped from the studio")
                if op == "frames":
                    return True, {"frames": self._frames()}
        except TryRefused as refused:
            return False, {"error": str(refused)}
        return False, {"error": f"op {op!r}: one of start, step, answer, stop, frames"}

    def _busy(self) -> str | None:
        """Why the robot is not free for a try now, or None. Only a person counts: with
        nobody in front, what runs is the robot's own idling (``wait``, ``sleep``)."""
        user = self.stack.controller.sessions.user_id
        if user is not None:
            return f"a session is open ({user}): a try waits until nobody is in a session"
        return None

    def _start(self, doc: object, state: object, step: bool) -> dict[str, Any]:
        if not isinstance(doc, dict):
            raise TryRefused("doc: the behavior, as a JSON object")
        if state is not None and not isinstance(state, str):
            raise TryRefused("state: the path of the state to run alone")
        busy = self._busy()
        if busy is not None:
            raise TryRefused(busy)
        if state:
            try:
                doc = one_state(doc, state)
            except StudioError as error:
                raise TryRefused(str(error)) from None
        try:
            spec = parse_text(document_text(doc), WHERE)
        except BehaviorError as error:
            raise TryRefused(f"it does not load: {error.problems[0]}") from None
        library = self.stack.library
        specs = {name: library.spec(name) for name in library.names}
        specs[spec.name] = spec
        problems = [p for p in check_references(specs) if p.startswith(f"{spec.name}:")]
        if problems:
            raise TryRefused(f"it does not load: {problems[0]}")
        now = self.clock()
        self._cancel(now)
        context = self.stack.controller.runner.context(spec.name)
        self.activity = BehaviorLibrary(specs, library.directory).create(spec.name, context)
        self.behavior = spec.name
        self._shown = None
        self._userdata = {}
        self.stepping = self.paused = step
        self.activity.start(now)
        self._report()
        return {"trying": spec.name, "state": state or None, "step": step}

    def _step(self) -> dict[str, Any]:
        activity = self._running()
        busy = self._busy()
        if busy is not None:
            raise TryRefused(busy)
        self.stepping, self.paused = True, False
        self._before = activity.state_path
        self._report()
        return {"from": self._before}

    def _running(self) -> Activity:
        if self.activity is None or self.activity.finished:
            raise TryRefused("no try runs")
        return self.activity

    def _answer(self, text: object) -> dict[str, Any]:
        if not isinstance(text, str):
            raise TryRefused("text: what the user says, screen:CHOICE or touch:PART")
        activity = self._running()
        event = parse_input(text)
        return {"taken": event is not None and activity.deliver(event)}

    def _stop(self, why: str) -> dict[str, Any]:
        stopped = self.activity is not None and not self.activity.finished
        self._cancel(self.clock(), why)
        return {"stopped": stopped}

    def _frames(self) -> list[str]:
        scene = self.stack.controller.deps.scene
        names = scene.frames.names if scene is not None else ()
        return ["user", *sorted(n for n in names if n.startswith(FRAME_PREFIXES[1:]))]

    # ---------------------------------------------------------------- the tick

    def tick(self, now: datetime) -> None:
        """After the controller's tick (under the daemon's lock): go on, hold still at a
        state while stepping, or give way to a session that began."""
        activity = self.activity
        if activity is None or activity.finished:
            return
        busy = self._busy()
        if busy is not None:
            self._cancel(now, busy.split(":", 1)[0])
            return
        if self.paused:
            return
        try:
            activity.tick(now)
        except Exception as error:  # a try's fault never stops the daemon's loop
            log.exception("try of %s", self.behavior)
            self._cancel(now, f"failed: {type(error).__name__}: {error}")
            return
        if self.stepping and activity.state_path != self._before:
            self.paused = True
        self._report()

    def _cancel(self, now: datetime, why: str | None = None) -> None:
        activity = self.activity
        if activity is not None and not activity.finished:
            activity.cancel(now)
            self._report(why)

    def _report(self, why: str | None = None) -> None:
        """Publish the try's state when its path or status changed."""
        activity = self.activity
        if activity is None:
            return
        status = activity.status.value if activity.status else "running"
        paused = self.paused and not activity.finished
        shown = (activity.state_path, status, paused)
        userdata = shown_userdata(activity.userdata)
        if shown == self._shown and userdata == self._userdata and why is None:
            return
        changed = {k: v for k, v in userdata.items() if self._userdata.get(k, ...) != v}
        self._shown, self._userdata = shown, userdata
        result = activity.result if activity.finished else None
        self.publish(
            TRY_STATE_KEY,
            {
                "behavior": self.behavior,
                "path": activity.state_path,
                "status": status,
                "finished": activity.finished,
                "paused": paused,
                "outcome": result.outcome if result is not None else None,
                "error": result.error if result is not None else None,
                "detail": why,
                "userdata": userdata,
                "changed": changed,
            },
        )


USERDATA_CHARS = 4000
"""A userdata value longer than this as JSON is shown cut (a try publishes every change)."""


def shown_userdata(userdata: dict[str, Any]) -> dict[str, Any]:
    """The userdata as JSON values for the page's table: a value JSON cannot carry is
    shown as its text, a long one cut to :data:`USERDATA_CHARS`."""
    out: dict[str, Any] = {}
    for key, value in userdata.items():
        text = json.dumps(value, default=str)
        if len(text) > USERDATA_CHARS:
            out[str(key)] = f"{text[:USERDATA_CHARS]}… ({len(text)} characters)"
        else:
            out[str(key)] = json.loads(text)
    return out
