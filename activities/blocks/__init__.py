"""The building blocks for Mini: generic, parameterized leaf states (ROS Commander's tools).

Each block declares its parameters once, as a pydantic model written just before it.
From that model come the loader's checks (:func:`param_problems`: unknown, missing and
mistyped parameters), the values a state gets each time it is entered
(:meth:`Block.bind_params`), and the block's part of the JSON Schema of behavior files
(``activities/behavior.schema.json``, see :func:`activities.schema.json_schema`). A new
block is a model, a class with its ``NAME`` and an entry in :data:`BLOCKS`::

    class LookAtParams(BlockParams):
        target: Text = Field(description="Who or what to look at: a user id or a place.")
        duration_s: float | None = Field(None, description="How long; null: until moved.")


    class LookAt(Block[LookAtParams]):
        NAME = "look_at"
        DOC = "Turn the head towards `target`; done when the robot looks at it."
        PARAMS = LookAtParams

        def begin(self, now: datetime) -> None:
            self.handles = []
            self.command("motion", "look_at", {"target": self.args.target}, now)

In a model, a field without a default is required; ``X | None = None`` is optional with
nothing as its default; ``Literal[...]`` is a choice; :data:`Text` is a string that a
bound placeholder fills with any value as it reads in a sentence (``6``, ``a, b and
c``); the ``description`` is the documentation (the schema carries it). A block reads
its values, typed, from ``self.args`` (an instance of its model).

Any parameter may be written as a placeholder, ``"{user.name}"`` (the loader checks the
rest, the schema allows it); a value holding placeholders is bound when the state is
entered and only then checked against the model (a value that still does not fit
fails the activity, naming the parameter). Values with no placeholder are checked at
load and validated once, then shared by every entry of the state: models are frozen.
A placeholder that binds to nothing leaves a parameter at its default (but an empty
string stays an empty string where any string is a value).

Blocks whose outcomes depend on their parameters (``ask``, ``decide``) work them out
from the parameters as written (:meth:`Block.outcomes_for`). Blocks that talk to the
robot go through the expression arbiter with the activity's source; a command that
fails or is never acknowledged fails the block (and the activity) with the reason.

The blocks by what they do: :mod:`~activities.blocks.speech` (speak, ask, menu),
:mod:`~activities.blocks.expression` (show, gesture, pose, leds, play_media),
:mod:`~activities.blocks.waiting` (wait, wait_event), :mod:`~activities.blocks.data`
(decide, set_param, set_data, sample, check) and :mod:`~activities.blocks.aiming`
(look_at, point_at, attend); what they share is in :mod:`~activities.blocks.base` and
:mod:`~activities.blocks.params`.
"""

from __future__ import annotations

from typing import Any

from activities.blocks.aiming import AimParams, Attend, AttendParams, LookAt, PointAt
from activities.blocks.base import Block, Countdown
from activities.blocks.data import Check, Decide, Sample, SetData, SetParam
from activities.blocks.expression import Gesture, Leds, PlayMedia, Pose, Show
from activities.blocks.params import (
    BlockParams,
    Text,
    accepts_any_string,
    holds_placeholder,
    param_problems,
)
from activities.blocks.speech import Ask, Menu, Speak, declines, match_answer, voice_settings
from activities.blocks.waiting import Wait, WaitEvent

BLOCKS: dict[str, type[Block[Any]]] = {
    block.NAME: block
    for block in (
        Speak,
        Ask,
        Show,
        Menu,
        Gesture,
        Pose,
        Leds,
        PlayMedia,
        Wait,
        WaitEvent,
        Decide,
        SetParam,
        SetData,
        Sample,
        Check,
        LookAt,
        PointAt,
        Attend,
    )
}
"""Every leaf block by the name used in behavior files."""

__all__ = [
    "BLOCKS",
    "AimParams",
    "Ask",
    "Attend",
    "AttendParams",
    "Block",
    "BlockParams",
    "Check",
    "Countdown",
    "Decide",
    "Gesture",
    "Leds",
    "LookAt",
    "Menu",
    "PlayMedia",
    "PointAt",
    "Pose",
    "Sample",
    "SetData",
    "SetParam",
    "Show",
    "Speak",
    "Text",
    "Wait",
    "WaitEvent",
    "accepts_any_string",
    "declines",
    "holds_placeholder",
    "match_answer",
    "param_problems",
    "voice_settings",
]
