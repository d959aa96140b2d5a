"""Gaze and pointing for behaviors: where the robot looks while an activity runs.

ROS Commander expresses motions relative to frames that perception produces, and keeps a
task frame's last known pose when there is no live estimate. Here the frames come from
the activity's context (``ActivityContext.frames``: ``user``, ``face:<id>``,
``object:<name>``), the joint angles from :mod:`dms.kernel.gaze`, and the commands go
out on the ``aim`` channel, which is best effort: a robot that ignores it (one that
predates it) never holds up the activity, which waits for an aim no longer than the
turn takes at the joints' speeds.

:class:`GazeKeeper` keeps the gaze on a frame while an activity runs: the ``attend``
block, and the ``attend:`` a behavior declares at its top (the shipped talk, quiz and
bingo look at the person they play with).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from datetime import datetime, timedelta
from typing import TYPE_CHECKING, Any

from activities.context import ActivityContext
from dms.kernel.body import JOINTS
from dms.kernel.expression import CommandHandle
from dms.kernel.frames import Located, UnknownFrame
from dms.kernel.gaze import Attention, AttentionSettings

if TYPE_CHECKING:
    from activities.task_frames import TaskFrames

USER = "user"
"""The frame of whoever is in front of the robot (the scene keeps it)."""

AIM_GRACE_S = 0.5
"""An aim is over this long after its turn should have ended, acknowledged or not."""


def locate(
    ctx: ActivityContext, frame: str, now: datetime, tasks: TaskFrames | None = None
) -> Located | None:
    """Where ``frame`` is now (live or last known), or None when it was never seen;
    ``tasks``: the activity's task frames, which ``frame`` may name."""
    if tasks is not None and frame in tasks:
        return tasks.locate(ctx.frames, frame, now)
    if ctx.frames is None:
        return None
    try:
        return ctx.frames.lookup(frame, now)
    except UnknownFrame:
        return None


def turn_seconds(joints: Mapping[str, float], targets: Mapping[str, float]) -> float:
    """How long the farthest joint takes to reach its target at its top speed."""
    seconds = (
        abs(angle - joints.get(name, 0.0)) / JOINTS[name].speed for name, angle in targets.items()
    )
    return max(seconds, default=0.0)


def aim_args(
    targets: Mapping[str, float], frame: str | None, located: Located | None
) -> dict[str, Any]:
    """An ``aim`` command's arguments: the joint targets (what a robot executes), and the
    frame and its position (for a robot that servos on its own perception); no frame:
    back to neutral, nothing to name."""
    args: dict[str, Any] = {
        "joints": {name: round(angle, 4) for name, angle in targets.items()},
        "frame": frame if located is not None else None,
    }
    if frame is not None and located is not None:
        x, y, z = located.position
        args["position"] = {"x": round(x, 4), "y": round(y, 4), "z": round(z, 4)}
        args["live"] = located.live
    return args


@dataclass
class Aim:
    """One aim command sent: over when done, failed, or its turn's time has passed."""

    handle: CommandHandle
    until: datetime

    def over(self, now: datetime) -> bool:
        return self.handle.finished or now >= self.until

    def stop(self, ctx: ActivityContext, now: datetime) -> None:
        """Withdraw it if it still runs (its state stopped, or a newer aim replaces it)."""
        if not self.handle.finished:
            ctx.expression.interrupt(self.handle, now)


def send_aim(
    ctx: ActivityContext,
    action: str,
    targets: Mapping[str, float],
    frame: str | None,
    located: Located | None,
    now: datetime,
) -> Aim:
    """Send one ``aim`` command for this activity; how long to wait for it at most."""
    handle = ctx.expression.request(
        ctx.source, "aim", action, aim_args(targets, frame, located), now
    )
    seconds = turn_seconds(ctx.joints, targets) + AIM_GRACE_S
    return Aim(handle, now + timedelta(seconds=seconds))


class GazeKeeper:
    """Keeps the gaze on a frame (``attend``): no jitter, neutral once the frame is gone."""

    def __init__(self, ctx: ActivityContext, frame: str, settings: AttentionSettings) -> None:
        self.ctx = ctx
        self.frame = frame
        self.settings = settings
        self.attention = Attention(frame, settings)
        self.current: Aim | None = None

    def update(self, now: datetime) -> None:
        """Once a tick: send a new gaze when the frame moved enough (or went stale)."""
        frames = self.ctx.frames
        if frames is None:
            return
        targets = self.attention.update(frames, now, self.ctx.joints.get("hip", 0.0))
        if targets is None:
            return
        self.withdraw(now)
        located = self.attention.located
        if located is not None and not located.live:
            located = None  # back to neutral: no target to name
        self.current = send_aim(self.ctx, "look_at", targets, self.frame, located, now)

    def withdraw(self, now: datetime) -> None:
        """Stop the gaze command still running (paused, stopped, or a newer gaze)."""
        if self.current is not None:
            self.current.stop(self.ctx, now)
        self.current = None

    def restart(self) -> None:
        """Look again from scratch (resumed after a pause: the person may have moved)."""
        self.attention = Attention(self.frame, self.settings)
