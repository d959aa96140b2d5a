"""The public messages of docs/contract.md as pydantic v2 models.

Inbound models validate what other processes publish: unknown fields are ignored,
wrong types, out-of-range values and missing required fields raise
``pydantic.ValidationError``. Outbound models are what the daemon publishes.
``dms schema DIR`` writes a JSON Schema for each (see :data:`SCHEMAS`).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated, Any, ClassVar, Literal, get_args

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    SerializerFunctionWrapHandler,
    StringConstraints,
    field_validator,
    model_serializer,
    model_validator,
)

from dms.kernel.activity_names import ACTIVITIES, current
from dms.kernel.ids import Identifier

ROBOT_ID_PATTERN = r"^[a-z0-9_-]+$"

Unit = Annotated[float, Field(ge=0.0, le=1.0, allow_inf_nan=False)]
ShortText = Annotated[str, StringConstraints(max_length=4096)]
ParamName = Annotated[str, StringConstraints(pattern=r"^[A-Za-z_][A-Za-z0-9_]{0,63}$")]
ParamValue = Annotated[str, StringConstraints(max_length=1024)] | bool | int | float


class Inbound(BaseModel):
    """A message another process publishes to the daemon."""

    model_config = ConfigDict(extra="ignore", strict=True, frozen=True, defer_build=True)


class Outbound(BaseModel):
    """A message the daemon publishes."""

    model_config = ConfigDict(extra="forbid", frozen=True, defer_build=True)


class _OmitsUnset(Outbound):
    """An outbound part whose optional additions (:attr:`_OPTIONAL`) are left out of the
    JSON while they are None: a message stays as it was until a field is filled."""

    _OPTIONAL: ClassVar[tuple[str, ...]] = ()

    @model_serializer(mode="wrap")
    def _omit_unset(self, handler: SerializerFunctionWrapHandler) -> dict[str, Any]:
        data: dict[str, Any] = handler(self)
        for name in self._OPTIONAL:
            if data.get(name, False) is None:
                del data[name]
        return data


# ---------------------------------------------------------------- inbound


Metres = Annotated[float, Field(ge=-100.0, le=100.0, allow_inf_nan=False)]
"""A coordinate in metres: a robot on a table perceives nothing 100 m away."""
QuaternionPart = Annotated[float, Field(ge=-1.0, le=1.0, allow_inf_nan=False)]


class Vector3(Inbound):
    """A position in metres (Foxglove's ``Vector3``)."""

    x: Metres
    y: Metres
    z: Metres


class Quaternion(Inbound):
    """An orientation (Foxglove's ``Quaternion``); normalised when used."""

    x: QuaternionPart
    y: QuaternionPart
    z: QuaternionPart
    w: QuaternionPart

    @model_validator(mode="after")
    def _not_zero(self) -> Quaternion:
        if self.x * self.x + self.y * self.y + self.z * self.z + self.w * self.w < 1e-6:
            raise ValueError("orientation must not be the zero quaternion")
        return self


class Pose(Inbound):
    """Where something is in the robot's base frame (x forward, y left, z up, metres;
    Foxglove's ``Pose``); no orientation: only its position is known."""

    position: Vector3
    orientation: Quaternion | None = None


class UserPerception(Inbound):
    """``perception/user``: who is in front of the robot."""

    present: bool
    user_id: Identifier | None = None
    ready: bool = False
    engagement: Unit | None = None
    face: Pose | None = None
    """Optional: the user's face in the robot's base frame."""


ObjectName = Annotated[str, StringConstraints(pattern=r"^[A-Za-z0-9_.-]{1,64}$")]
"""An object's or a tag's name: its frame is ``object:<name>``."""


class PerceivedObject(Inbound):
    """One named object or tag seen by the robot."""

    name: ObjectName
    pose: Pose


class ObjectsPerception(Inbound):
    """``perception/objects`` (optional input): the objects or tags seen now, with poses.
    An object not in the list is not seen now; the robot keeps its last known pose."""

    objects: list[PerceivedObject] = Field(max_length=64)


JointName = Literal["hip", "left_arm", "right_arm", "neck", "head"]
Radians = Annotated[float, Field(ge=-6.3, le=6.3, allow_inf_nan=False)]


class RobotJoints(Inbound):
    """``robot/joints``: the robot's joint positions in radians (the simulated Mini
    publishes it; an external robot may, with ``--robot zenoh``)."""

    positions: dict[str, Radians] = Field(
        max_length=16, json_schema_extra={"propertyNames": {"enum": list(get_args(JointName))}}
    )
    """By joint: ``hip``, ``left_arm``, ``right_arm``, ``neck``, ``head``."""
    time: str | None = None
    """When the positions were measured (ISO-8601 UTC); informative."""

    @field_validator("positions")
    @classmethod
    def _known_joints(cls, positions: dict[str, float]) -> dict[str, float]:
        unknown = sorted(set(positions) - set(get_args(JointName)))
        if unknown:
            raise ValueError(f"unknown joint {unknown[0]!r}")
        return positions


class Touch(Inbound):
    """``perception/touch``: one touch event."""

    part: Literal["right_shoulder", "left_shoulder", "head", "belly"]
    kind: Literal["tap", "caress", "hit"]


class Speech(Inbound):
    """``perception/speech``: one recognized utterance."""

    text: ShortText
    confidence: Unit


class ScreenChoice(Inbound):
    """``perception/screen``: one option tapped on the touch screen."""

    choice: Annotated[str, StringConstraints(min_length=1, max_length=256)]


class ProfileParams(Inbound):
    """``params/robot`` and ``params/env``: named values, merged into the profile."""

    model_config = ConfigDict(extra="forbid", strict=True, frozen=True, defer_build=True)
    values: dict[ParamName, ParamValue] = Field(max_length=256)

    @classmethod
    def from_payload(cls, payload: Any) -> ProfileParams:
        return cls.model_validate({"values": payload})

    @field_validator("values")
    @classmethod
    def _finite(cls, values: dict[str, Any]) -> dict[str, Any]:
        for name, value in values.items():
            if (isinstance(value, float) and value != value) or value in (
                float("inf"),
                float("-inf"),
            ):
                raise ValueError(f"{name} is not a finite number")
        return values


RequestAction = Literal["start", "cancel", "pause", "resume", "reload_rules"]


class Request(Inbound):
    """``request``: a request from another program (a caregiver's app, a test)."""

    action: RequestAction
    activity: str | None = None
    by: Identifier | None = None
    """Who asked (an app, a caregiver): an identifier, so it cannot forge a log line."""

    @field_validator("activity")
    @classmethod
    def _known_activity(cls, activity: str | None) -> str | None:
        if activity is not None and activity not in ACTIVITIES:
            raise ValueError(current().unknown(activity))
        return activity


FeedbackStatus = Literal["started", "done", "interrupted", "failed"]


class RobotFeedback(Inbound):
    """``robot/feedback``: an external robot reporting on a command."""

    id: Identifier
    status: FeedbackStatus
    detail: ShortText | None = None


# ---------------------------------------------------------------- outbound

Channel = Literal["speech", "screen", "led", "motion", "media", "aim"]
"""``aim``: turning joints toward a frame (``look_at``, ``point_at``,
``turn_to``); best effort, so a robot that ignores it loses nothing (see the arbiter)."""


class RobotCommand(Outbound):
    """``robot/command``: one expression command."""

    id: str
    channel: Channel
    action: str
    args: dict[str, Any] = Field(default_factory=dict)


class ErrorReport(Outbound):
    """``dms/errors``: one rejected input or runtime problem."""

    key: str
    error: str
    time: str


class UserState(_OmitsUnset):
    _OPTIONAL = ("proactivity", "p_user")

    id: str
    ready: bool
    proactivity: str | None = None
    """Optional: the user's proactivity as the profile holds it (``low``, ``moderate``,
    ``high`` or ``unknown``), for a viewer."""
    p_user: float | None = None
    """Optional: the probability that the user takes the initiative in this session."""


class ActivityState(Outbound):
    name: str
    manager: str
    status: Literal["running", "paused"]
    state: str


class MotivationSnapshot(_OmitsUnset):
    _OPTIONAL = ("thresholds",)

    dominant: str | None
    drives: dict[str, float]
    motivations: dict[str, float]
    wellbeing: float
    thresholds: dict[str, float] | None = None
    """Optional: each drive's threshold (below it the drive gives no motivation), for a
    viewer's chart."""


InputStatus = Literal["ok", "stale", "missing", "not_published"]
Mode = Literal["motivation", "autonomous", "user_choice", "hybrid"]


class DmsState(_OmitsUnset):
    """``dms/state``: the daemon's state, every tick and after every decision."""

    _OPTIONAL = ("started", "failing_channel")

    robot: str
    tick: int
    time: str
    mode: Mode
    user: UserState | None
    activity: ActivityState | None
    suspended: ActivityState | None
    motivation: MotivationSnapshot
    inputs: dict[str, InputStatus]
    robot_link: Literal["ok", "offline"] = "ok"
    """``offline``: too many commands in a row not acknowledged; no activity starts
    until the robot answers again (feedback, or its ``alive/robot/feedback`` token)."""
    failing_channel: Channel | None = None
    """Optional: the output channel whose commands keep failing (two or more in a row
    reported failed, none done since), e.g. ``speech``; left out while none fails. Starts
    then back off as while offline: one is tried after a wait that doubles."""
    reloads: int = 0
    """Reloads of the rules and behaviors finished since the start (SIGHUP, ``reload_rules``):
    a client that asked for one knows it is in force once this has grown."""
    pending_writes: int = 0
    """Profile writes the daemon acknowledged that are not in the database yet (queued,
    being written, or spooled during an outage): 0 once a state published after an
    action shows it, what the action wrote is stored (another robot of the fleet reads
    it); a number that stays up says the database is away."""
    storage: Literal["ok", "degraded"] = "ok"
    """``degraded``: acknowledged writes wait for the database (it is away, its disk is
    full, its file was deleted); they are spooled and written once it takes them again."""
    started: str | None = None
    """Optional: when the daemon started (ISO-8601), for a viewer opened later; left out
    by a state not published by a daemon (a simulation)."""


DecisionAction = Literal["start", "pause", "resume", "cancel", "complete", "fail", "ask"]
Reason = Literal[
    "motivation",
    "motivation_changed",
    "user_request",
    "user_choice",
    "preference",
    "agenda",
    "activity_error",
    "activity_redirect",
    "completed",
    "confirm_cancel",
    "user_left",
    "input_missing",
    "user_arrived",
    "notification",
    "feedback",
    "general_question",
    "shutdown",
    "resumed",
]
ChosenBy = Literal["robot", "user", "agenda", "motivation"]


class ModeWhy(_OmitsUnset):
    """The mode coin: the user takes the initiative (a menu) if ``draw < p_user``."""

    _OPTIONAL = ("left_to_robot",)

    p_user: float | None = None
    """The probability that the user takes the initiative (the coin's threshold)."""
    draw: float | None = None
    """The coin (uniform in 0..1); None when none was tossed (see ``left_to_robot``)."""
    mode: str | None = None
    left_to_robot: bool | None = None
    """Optional: True when no coin was tossed because the user had just left the choice to
    the robot (declined the menu, or let it go unanswered)."""


class PreferenceWhy(Outbound):
    """One activity and how much the user is predicted to like it (0 to 1)."""

    activity: str
    score: float


class MotivationWhy(Outbound):
    dominant: str | None = None
    drives: dict[str, float] = Field(default_factory=dict)


class RuleWhy(Outbound):
    """The DMSL rule that decided: its component, where its ``activate`` stands."""

    component: str
    file: str | None = None
    line: int | None = None
    activate: list[str] = Field(default_factory=list)


DrawKind = Literal["ranking", "novelty", "sampling", "random", "chooser"]
"""What picked the robot's activity among its candidates (docs/contract.md ``why``)."""


class NoveltyWhy(Outbound):
    """The novelty coin: an activity the user never did is picked if ``draw < probability``."""

    draw: float
    probability: float
    untried: list[str]
    """The candidates the user never did, among which a novelty pick is drawn."""


class ChoiceWhy(_OmitsUnset):
    """Which random draw picked the robot's activity, and among what."""

    _OPTIONAL = ("novelty", "samples", "excluded", "ranking")

    by: DrawKind
    candidates: list[str]
    """What the pick was among."""
    excluded: list[str] | None = None
    """Left out of the candidates: the last activity (never twice in a row)."""
    novelty: NoveltyWhy | None = None
    """The novelty coin, when one was tossed (some candidate never done)."""
    samples: dict[str, float] | None = None
    """Thompson sampling: one liking drawn from each candidate's belief; the highest won."""
    ranking: list[str] | None = None
    """The predicted ranking of the candidates, best first: the first won (``by: ranking``)."""


class Why(_OmitsUnset):
    """What decided (docs/contract.md ``why``); every field optional."""

    _OPTIONAL = ("choice",)

    mode: ModeWhy | None = None
    preferences: list[PreferenceWhy] | None = None
    """The top three activities with their predicted scores."""
    motivation: MotivationWhy | None = None
    rule: RuleWhy | None = None
    evidence: str | None = None
    """For cancels and failures: what was seen."""
    choice: ChoiceWhy | None = None
    """Optional: for the robot's own choice of an activity, the draw that picked it."""


class Decision(Outbound):
    """``dms/decision``: one decision, with why it was taken."""

    tick: int
    time: str
    action: DecisionAction
    activity: str | None
    manager: str | None
    reason: Reason
    chosen_by: ChosenBy | None = None
    detail: str | None = None
    why: Why | None = None


INBOUND_BY_KEY: dict[str, type[Inbound]] = {
    "perception/user": UserPerception,
    "perception/touch": Touch,
    "perception/speech": Speech,
    "perception/screen": ScreenChoice,
    "perception/objects": ObjectsPerception,
    "params/robot": ProfileParams,
    "params/env": ProfileParams,
    "request": Request,
    "robot/feedback": RobotFeedback,
    "robot/joints": RobotJoints,
}
"""Every input key (after ``robots/<id>/``) and the model that validates it."""

SCHEMAS: dict[str, type[BaseModel]] = {
    "perception_user": UserPerception,
    "perception_touch": Touch,
    "perception_speech": Speech,
    "perception_screen": ScreenChoice,
    "perception_objects": ObjectsPerception,
    "params": ProfileParams,
    "request": Request,
    "robot_feedback": RobotFeedback,
    "robot_joints": RobotJoints,
    "robot_command": RobotCommand,
    "dms_errors": ErrorReport,
    "dms_state": DmsState,
    "dms_decision": Decision,
}


def json_schema(model: type[BaseModel]) -> dict[str, Any]:
    """The JSON Schema of one message; ``params/*`` payloads are plain objects."""
    if model is ProfileParams:
        inner = ProfileParams.model_json_schema()["properties"]["values"]
        return {"title": "ProfileParams", **inner}
    return model.model_json_schema()


def write_schemas(directory: Path) -> list[Path]:
    """Write one ``<name>.schema.json`` per message into ``directory``."""
    directory.mkdir(parents=True, exist_ok=True)
    written = []
    for name, model in SCHEMAS.items():
        path = directory / f"{name}.schema.json"
        path.write_text(json.dumps(json_schema(model), indent=2, sort_keys=True) + "\n")
        written.append(path)
    return written
