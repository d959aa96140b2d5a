"""Gaze and pointing: blocks that turn the head, the hip or an arm toward a frame.

A frame is ``user`` (whoever is in front), ``face:<id>`` or ``object:<name>``, as
perception locates it (:mod:`activities.gaze`).
"""

from __future__ import annotations

from datetime import datetime
from typing import ClassVar, Literal, TypeVar

from pydantic import (
    Field,
)

from activities.blocks.base import Block, Countdown
from activities.blocks.params import BlockParams
from activities.engine import Status
from activities.gaze import USER, Aim, GazeKeeper, locate, send_aim
from dms.kernel.expression import CommandStatus
from dms.kernel.frames import Located
from dms.kernel.gaze import AttentionSettings, aim, point


class AimParams(BlockParams):
    frame: str = Field(
        USER, description="What to aim at: user (whoever is in front), face:<id>, object:<name>."
    )
    last_known: bool = Field(
        True,
        description="Not seen now: aim where it was last seen (ROS Commander's task frames); "
        "false: end with lost.",
    )


AP = TypeVar("AP", bound=AimParams)


class Aiming(Block[AP]):
    """Turns joints toward a frame once: ``lost`` when there is nothing to aim at (never
    seen, or not seen now and ``last_known`` false), else ``done`` once the aim is over
    (done, failed or ignored: the aim channel is best effort)."""

    OUTCOMES = ("done", "lost")
    ACTION: ClassVar[str] = ""
    aim: Aim | None = None

    def targets(self, located: Located) -> dict[str, float]:
        """The joint angles that aim at ``located`` (in the base frame)."""
        raise NotImplementedError

    def begin(self, now: datetime) -> None:
        self.handles = []
        self.aim = None
        located = locate(self.rt.ctx, self.args.frame, now, self.rt.task_frames)
        if located is None or (not located.live and not self.args.last_known):
            return
        targets = self.targets(located)
        self.aim = send_aim(self.rt.ctx, self.ACTION, targets, self.args.frame, located, now)

    def update(self, now: datetime) -> Status:
        if self.aim is None:
            return self.finish("lost")
        if not self.aim.over(now):
            return Status.RUNNING
        if self.aim.handle.status is CommandStatus.SENT:  # never acknowledged: free the lane
            self.aim.stop(self.rt.ctx, now)
        return self.finish("done")

    def withdraw(self, now: datetime) -> None:
        super().withdraw(now)
        if self.aim is not None:
            self.aim.stop(self.rt.ctx, now)


class LookAt(Aiming[AimParams]):
    NAME = "look_at"
    DOC = "Turn the head (the hip if needed) toward a frame; done when it looks there."
    PARAMS = AimParams
    ACTION = "look_at"

    def targets(self, located: Located) -> dict[str, float]:
        return aim(located, self.rt.ctx.joints.get("hip", 0.0))


class PointAtParams(AimParams):
    frame: str = Field(description="What to point at: object:<name>, user, face:<id>.")
    arm: Literal["left", "right"] | None = Field(
        None, description="The arm; by default the one on the frame's side."
    )


class PointAt(Aiming[PointAtParams]):
    NAME = "point_at"
    DOC = "Point an arm (the hip turning) at a frame; done when it points there."
    PARAMS = PointAtParams
    ACTION = "point_at"

    def targets(self, located: Located) -> dict[str, float]:
        side = self.args.arm or ("left" if located.position[1] > 0 else "right")
        return point(located, f"{side}_arm")


class AttendParams(BlockParams):
    frame: str = Field(USER, description="Whom to keep looking at: user, face:<id>, object:<name>.")
    neutral_after_s: float = Field(
        3.0, gt=0, description="Not seen for this long: look ahead again (neutral)."
    )
    dead_band_rad: float = Field(
        0.06, ge=0, description="A move smaller than this is not made: no jitter."
    )
    max_shifts_per_s: float = Field(
        3.0, gt=0, description="At most this many gaze shifts a second."
    )

    def settings(self) -> AttentionSettings:
        return AttentionSettings(self.dead_band_rad, self.max_shifts_per_s, self.neutral_after_s)


class AttendBlockParams(AttendParams):
    seconds: float | None = Field(None, description="How long; null: until the state is stopped.")


class Attend(Block[AttendBlockParams]):
    NAME = "attend"
    DOC = "Keep the gaze on a frame (the user's face) while other states run beside it."
    PARAMS = AttendBlockParams
    keeper: GazeKeeper | None = None

    def begin(self, now: datetime) -> None:
        self.handles = []
        self.keeper = GazeKeeper(self.rt.ctx, self.args.frame, self.args.settings())
        self.countdown = Countdown(now, self.args.seconds)

    def on_pause(self, now: datetime) -> None:
        self.withdraw(now)
        self.countdown.pause(now)

    def on_resume(self, now: datetime) -> None:
        assert self.keeper is not None  # entered before it could pause
        self.keeper.restart()
        self.countdown.resume(now)

    def withdraw(self, now: datetime) -> None:
        super().withdraw(now)
        if self.keeper is not None:
            self.keeper.withdraw(now)

    def update(self, now: datetime) -> Status:
        if self.countdown.over(now):
            return self.finish("done")
        assert self.keeper is not None  # made on entry
        self.keeper.update(now)
        return Status.RUNNING
