"""The robot's other channels: the screen, gestures (toward a frame), poses, LEDs, media."""

from __future__ import annotations

from datetime import datetime
from typing import Annotated, Any, Literal

from pydantic import (
    Field,
    field_validator,
    model_validator,
)

from activities.blocks.base import Block
from activities.blocks.params import BlockParams, Text
from activities.engine import Status, Wake
from activities.gaze import Aim, locate, send_aim
from dms.kernel.body import JOINTS
from dms.kernel.gaze import turn_toward


class ShowParams(BlockParams):
    text: Text = Field("", description="Text to show.")
    image: Text | None = Field(None, description="An image file to show.")
    face: str | None = Field(
        None, description="A face for the screen eyes: neutral, happy, closed_eyes, ..."
    )


class Show(Block[ShowParams]):
    NAME = "show"
    DOC = "Show text, an image or a face on the screen."
    PARAMS = ShowParams

    def begin(self, now: datetime) -> None:
        self.handles = []
        args = {k: v for k, v in dict(self.args).items() if v not in (None, "")}
        self.command("screen", "show", args, now)


class GestureParams(BlockParams):
    name: str = Field(description="One of the robot's gestures: nod, wave, bow, dance_step, ...")
    duration_s: float | None = Field(None, description="By default the gesture's own.")
    toward: str | None = Field(
        None,
        description="A frame to make it toward (user, face:<id>, object:<name>): the hip "
        "turns to it first and follows it while the gesture lasts (ROS Commander's task frames).",
    )


TOWARD_DEAD_BAND_RAD = 0.06
"""A gesture made toward a frame turns again only when the frame moved more than this."""


class Gesture(Block[GestureParams]):
    NAME = "gesture"
    DOC = "Move: nod, wave, bow, dance_step, ... (durations are the robot's), toward a frame."
    PARAMS = GestureParams
    turn: Aim | None = None
    """The hip's turn toward ``toward``, while it may still run."""

    def begin(self, now: datetime) -> None:
        self.handles = []
        self.turn = None
        self.hip: float | None = None
        self._retarget(now)
        args: dict[str, Any] = {"name": self.args.name}
        if self.args.duration_s is not None:
            args["duration_s"] = self.args.duration_s
        self.command("motion", "gesture", args, now)

    def _retarget(self, now: datetime) -> None:
        """Turn the hip toward ``toward`` (again, if it moved): a live frame, or its
        last known pose when the gesture starts."""
        frame = self.args.toward
        if frame is None:
            return
        located = locate(self.rt.ctx, frame, now, self.rt.task_frames)
        if located is None or (self.hip is not None and not located.live):
            return
        hip = turn_toward(located)["hip"]
        if self.hip is not None and abs(hip - self.hip) < TOWARD_DEAD_BAND_RAD:
            return
        if self.turn is not None:
            self.turn.stop(self.rt.ctx, now)
        self.hip = hip
        self.turn = send_aim(self.rt.ctx, "turn_to", {"hip": hip}, frame, located, now)

    def withdraw(self, now: datetime) -> None:
        super().withdraw(now)
        if self.turn is not None:
            self.turn.stop(self.rt.ctx, now)

    def update(self, now: datetime) -> Status:
        if self.args.toward is not None:
            self._retarget(now)
        return super().update(now)

    def wake(self, now: datetime) -> Wake | None:
        """Without ``toward``, this is Block's ``update``; with it, it follows a frame."""
        if self.args.toward is not None or not self.updates_as(Gesture):
            return None
        return self.waiting_on_commands()


Keyframe = dict[str, float]
"""A pose: the angle (radians) of each joint named (hip, neck, head, left_arm, right_arm)."""


class PoseParams(BlockParams):
    keyframes: list[Keyframe] = Field(
        min_length=1,
        description="The poses to move through, in order: joint -> radians. The studio's "
        "Record button takes the robot's current joints as the next keyframe.",
    )
    seconds: list[Annotated[float, Field(gt=0, le=60)] | None] = Field(
        [],
        description="How long each move takes, one per keyframe (null, or missing: as fast "
        "as the joints go).",
    )

    @model_validator(mode="after")
    def _one_time_per_keyframe(self) -> PoseParams:
        if len(self.seconds) > len(self.keyframes):
            raise ValueError(
                f"seconds: {len(self.seconds)} times for {len(self.keyframes)} keyframes"
            )
        return self

    @field_validator("keyframes")
    @classmethod
    def _known_joints(cls, keyframes: list[Keyframe]) -> list[Keyframe]:
        for index, keyframe in enumerate(keyframes):
            unknown = sorted(set(keyframe) - set(JOINTS))
            if unknown:
                known = ", ".join(JOINTS)
                raise ValueError(f"keyframe {index + 1}: no joint {unknown[0]!r} ({known})")
        return keyframes


class Pose(Block[PoseParams]):
    """A gesture of one's own: each keyframe is sent as a ``motion`` ``pose`` command
    once the one before it is over, as ROS Commander replays recorded waypoints."""

    NAME = "pose"
    DOC = "Move through recorded poses (keyframes of joint angles), one after the other."
    PARAMS = PoseParams

    def begin(self, now: datetime) -> None:
        self.handles = []
        self.next_keyframe = 0
        self._send(now)

    def _send(self, now: datetime) -> None:
        index = self.next_keyframe
        self.next_keyframe += 1
        args: dict[str, Any] = {"joints": dict(self.args.keyframes[index])}
        seconds = self.args.seconds[index] if index < len(self.args.seconds) else None
        if seconds is not None:
            args["duration_s"] = seconds
        self.command("motion", "pose", args, now)

    def update(self, now: datetime) -> Status:
        error = self.command_error()
        if error is not None:
            return self.fail(error)
        if not self.commands_done():
            return Status.RUNNING
        if self.next_keyframe < len(self.args.keyframes):
            self._send(now)
            return Status.RUNNING
        return self.finish(self.OUTCOMES[0])

    def wake(self, now: datetime) -> Wake | None:
        return self.waiting_on_commands()


class LedsParams(BlockParams):
    color: str = Field(description="A colour name or #rrggbb.")
    pattern: str = Field("solid", description="solid, blink, pulse or breathing.")


class Leds(Block[LedsParams]):
    NAME = "leds"
    DOC = "Set the cheek and heart LEDs."
    PARAMS = LedsParams

    def begin(self, now: datetime) -> None:
        self.handles = []
        self.command("led", "set", dict(self.args), now)


class PlayMediaParams(BlockParams):
    title: Text = Field(description="What is played, as said and shown.")
    file: Text | None = Field(None, description="The local media file.")
    kind: Literal["music", "video", "audio", "photos"] = "music"
    duration_s: float = Field(60.0, description="How long it plays.")


class PlayMedia(Block[PlayMediaParams]):
    NAME = "play_media"
    DOC = "Play a song, video or photo album from local media; done when it ends."
    PARAMS = PlayMediaParams

    def begin(self, now: datetime) -> None:
        self.handles = []
        args = {k: v for k, v in dict(self.args).items() if v is not None}
        self.command("media", "play", args, now)
