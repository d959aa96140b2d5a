"""Trying a behavior, or one of its states, on the simulated Mini from the page.

A :class:`Trial` wraps :class:`activities.stepper.BehaviorRun` (what ``dms behavior
step`` runs) on the document being edited, saved or not: each step goes on to the next
state and reports the state path (the page lights it), the userdata and what changed,
the robot's commands, and what the robot shows: its last sentence, its screen and its
joints. One state alone runs as a behavior of that one state whose outcomes end it.
A user sits in front of the simulated Mini (the frame ``user``), so that ``look_at``,
``point_at`` and ``attend`` turn its joints as they would toward a person, and a marker
lies on the table (``object:tag``), which the page may hide and show again: a task frame
defined on it stays where it was last known while it is hidden.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Mapping
from datetime import datetime
from typing import TYPE_CHECKING, Any

from activities.errors import BehaviorError
from activities.library import BehaviorLibrary
from activities.spec import parse_text
from activities.stepper import BehaviorRun, Step, parse_input
from dms.kernel.body import NEUTRAL, body_frames
from dms.kernel.frames import FrameStore, pose
from dms.kernel.ports import RobotPort
from dms.studio.check import WHERE, document_text, parse_message, state_outcomes, walk
from dms.studio.errors import StudioError

if TYPE_CHECKING:
    from dms.studio.folder import Folder

RobotFactory = Callable[[int], RobotPort]
"""Makes the robot a trial drives, from its seed (the composition root passes the
simulated Mini: the application floor does not import ``sim``)."""
MAX_S = 600.0
"""Virtual seconds one step may wait for the next state (a question times out sooner)."""
SAID_KEPT = 6
USER_FACE_AT = (0.8, 0.25, 0.45)
"""Where the trial's user's face is, in metres from the robot's base: in front, a little to
its left, at head height."""
MARKER = "object:tag"
MARKER_AT = (0.5, -0.2, 0.0)
"""Where the trial's marker lies: on the table, in front of the robot, a little to its right."""


def seated_user(now: datetime) -> FrameStore:
    """The body's frames, a user's face and the marker seen at ``now`` (live for the whole
    trial, unless the marker is hidden)."""
    frames = FrameStore(body_frames(NEUTRAL))
    frames.set("user", pose(USER_FACE_AT), stamp=now)
    frames.set(MARKER, pose(MARKER_AT), stamp=now)
    return frames


def one_state(doc: Mapping[str, Any], path: str) -> dict[str, Any]:
    """A behavior of the state at ``path`` alone, each of its outcomes ending it."""
    states = dict(walk(doc.get("states") or {}))
    if path not in states:
        raise StudioError(f"no state {path!r}", 404)
    outcomes = state_outcomes(doc, {}).get(path, [])
    state = {key: value for key, value in states[path].items() if key != "transitions"}
    if outcomes:
        state["transitions"] = {outcome: outcome for outcome in outcomes}
    out: dict[str, Any] = {"name": doc.get("name"), "outcomes": outcomes or ["done"]}
    if isinstance(doc.get("userdata"), dict):
        out["userdata"] = doc["userdata"]
    out["states"] = {path.rsplit("/", 1)[-1]: state}
    return out


class Trial:
    """One run on a fresh simulated robot, advanced a state at a time."""

    def __init__(
        self, folder: Folder, doc: Mapping[str, Any], robot: RobotPort, seed: int = 0
    ) -> None:
        try:
            spec = parse_text(document_text(doc), WHERE)
        except BehaviorError as error:
            shown = "; ".join(
                f"{m.path or 'behavior'}: {m.text}" for m in map(parse_message, error.problems[:3])
            )
            raise StudioError(f"it does not load yet: {shown}", 422) from None
        specs = {**folder.others(spec.name), spec.name: spec}
        self.robot = robot
        self.run = BehaviorRun(BehaviorLibrary(specs, folder.directory), spec, robot, seed=seed)
        self.run.activity.runtime.ctx.frames = seated_user(self.run.clock.now())
        self.lock = threading.Lock()
        self.said: list[str] = []
        self.screen: dict[str, Any] = {}
        self.started = False

    def step(self) -> dict[str, Any]:
        """Start, or go on to the next state; what happened, for the page."""
        with self.lock:
            if not self.started:
                self.started = True
                return self._report(self.run.begin())
            if self.run.activity.finished:
                return self._report(None)
            return self._report(self.run.next_state(max_s=MAX_S))

    def answer(self, text: str) -> bool:
        """The user's answer (``screen:CHOICE``, ``touch:PART`` or words said)."""
        with self.lock:
            try:
                event = parse_input(text)
            except ValueError as error:
                raise StudioError(f"not understood: {str(error).splitlines()[0]}") from None
            return event is not None and self.run.deliver(event)

    def show_marker(self, seen: bool) -> bool:
        """Hide the marker (the scene forgets it, as when it is taken away) or show it
        again where it lies; whether it is seen now."""
        with self.lock:
            frames = self.run.activity.runtime.ctx.frames
            if frames is None:
                return False
            if seen:
                frames.set(MARKER, pose(MARKER_AT), stamp=self.run.clock.now())
            else:
                frames.forget(MARKER)
            return seen

    def stop(self) -> None:
        with self.lock:
            if not self.run.activity.finished:
                self.run.activity.cancel(self.run.clock.now())

    def joints(self) -> dict[str, float]:
        """The robot's joints now (neutral for a robot that does not report them)."""
        reader = getattr(self.robot, "joints", None)
        if reader is None:
            return dict(NEUTRAL)
        return {
            name: round(float(value), 3) for name, value in reader(self.run.clock.now()).items()
        }

    def _report(self, step: Step | None) -> dict[str, Any]:
        activity = self.run.activity
        commands = []
        for command in step.commands if step is not None else []:
            commands.append(
                {"channel": command.channel, "action": command.action, "args": command.args}
            )
            if command.channel == "speech" and command.action == "say":
                self.said = [*self.said, str(command.args.get("text", ""))][-SAID_KEPT:]
            elif command.channel == "screen":
                self.screen = dict(command.args)
        result = activity.result if activity.finished else None
        return {
            "t": round(self.run.t, 2),
            "path": activity.state_path,
            "status": activity.status.value if activity.status else "running",
            "userdata": step.userdata if step is not None else dict(activity.userdata),
            "changed": step.changed if step is not None else {},
            "commands": commands,
            "awaiting_answer": not activity.finished and self.run.awaiting_answer,
            "finished": activity.finished,
            "outcome": result.outcome if result is not None else None,
            "error": result.error if result is not None else None,
            "robot": {"said": self.said, "screen": self.screen, "joints": self.joints()},
        }
