"""The building blocks for Mini: generic, parameterized leaf states (ROS Commander's tools).

Each block declares its parameters once, as a pydantic model written just before it.
From that model come the loader's checks (:func:`param_problems`: unknown, missing and
mistyped parameters), the values a state gets each time it is entered
(:meth:`Block.bind_params`), and the block's part of the JSON Schema of behavior files
(``activities/behavior.schema.json``, see :func:`activities.spec.json_schema`). A new
block is a model, a class and an entry in :data:`BLOCKS`::

    class LookAtParams(BlockParams):
        target: Text = Field(description="Who or what to look at: a user id or a place.")
        duration_s: float | None = Field(None, description="How long; null: until moved.")


    class LookAt(Block[LookAtParams]):
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
"""

from __future__ import annotations

import copy
import functools
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from datetime import datetime, timedelta
from typing import Annotated, Any, ClassVar, Generic, Literal, TypeVar, cast

from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    ValidationError,
    ValidationInfo,
)

from activities.engine import Event, Io, Node, Runtime, Status, Wake
from activities.errors import BehaviorError
from activities.gaze import USER, Aim, GazeKeeper, locate, send_aim
from activities.synonyms import match_activity
from activities.template import as_text, has_placeholder, is_single_placeholder, render
from dms.kernel.activity_names import USER_SELECTABLE
from dms.kernel.expression import CommandHandle, CommandStatus, Priority
from dms.kernel.frames import Located
from dms.kernel.gaze import AttentionSettings, aim, point, turn_toward
from dms.kernel.messages import Channel, ScreenChoice, Speech, Touch
from dms.kernel.words import digits

# ---------------------------------------------------------------- parameters


class BlockParams(BaseModel):
    """The parameters of a block (or a container) as a behavior file writes them.

    Unknown names are refused. Frozen: one instance may serve every entry of a state.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    PLACEHOLDERS: ClassVar[frozenset[str] | None] = None
    """The parameters that may be written as a placeholder; None: all of them (a block
    binds them when its state is entered). Containers bind none but an iterator's
    ``items``."""

    @classmethod
    def may_bind(cls, key: str) -> bool:
        """Whether parameter ``key`` may be written as a placeholder."""
        return cls.PLACEHOLDERS is None or key in cls.PLACEHOLDERS


_BINDING: dict[str, bool] = {"binding": True}
"""The validation context of a state's entry, where placeholders have been bound."""


def _bound_text(value: Any, info: ValidationInfo) -> Any:
    """A bound value read as text (``8``, ``a, b and c``); a value written in the file
    itself must be a string already (the loader validates without this context)."""
    if info.context is _BINDING and value is not None and not isinstance(value, str):
        return as_text(value)
    return value


Text = Annotated[str, BeforeValidator(_bound_text)]
"""A string; a placeholder that binds to another value gives that value as text."""


def accepts_any_string(schema: Mapping[str, Any]) -> bool:
    """Whether a JSON Schema takes every string (a placeholder then needs no mention)."""
    if "anyOf" in schema:
        return any(accepts_any_string(option) for option in schema["anyOf"])
    constrained = {"enum", "const", "pattern", "minLength", "maxLength", "format"}
    kind = schema.get("type")
    return (kind is None or kind == "string") and not constrained & schema.keys()


_WORDS = {
    "string": "string",
    "integer": "integer",
    "number": "number",
    "boolean": "boolean",
    "object": "mapping",
    "null": "null",
}


def _expected(schema: Mapping[str, Any]) -> str:
    """What a field's JSON Schema asks for, in the words of the loader's messages."""
    if "anyOf" in schema:
        return " or ".join(_expected(option) for option in schema["anyOf"])
    kind = schema.get("type")
    if "enum" in schema:
        return f"{_WORDS.get(str(kind), 'value')} one of {list(schema['enum'])}"
    if kind == "array":
        items = schema.get("items") or {}
        return f"list of {_expected(items)}s" if items.get("type") else "list"
    return _WORDS.get(str(kind), "anything")


@dataclass(frozen=True)
class _Fields:
    """What the loader and the binding need to know of a model, worked out once."""

    names: tuple[str, ...]
    """The parameters as written (a field's alias where it has one: ``in``)."""
    required: frozenset[str]
    text: frozenset[str]
    """Parameters that take any string: an empty one is a value, not nothing."""
    expected: dict[str, str]
    """Each parameter's type in words (``string``, ``list of strings``, ...)."""


@functools.cache
def _fields(model: type[BlockParams]) -> _Fields:
    properties = model.model_json_schema()["properties"]
    names = tuple(field.alias or name for name, field in model.model_fields.items())
    required = frozenset(
        field.alias or name for name, field in model.model_fields.items() if field.is_required()
    )
    text = frozenset(key for key in names if accepts_any_string(properties[key]))
    return _Fields(names, required, text, {key: _expected(properties[key]) for key in names})


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 120 else text[:117] + "..."


def _explain(
    model: type[BlockParams],
    error: ValidationError,
    values: Mapping[str, Any],
    deferred: frozenset[str] = frozenset(),
) -> list[tuple[str | None, str]]:
    """One ``(parameter, message)`` per parameter pydantic refused, in the order
    written, then the missing ones (not those in ``deferred``: written as placeholders)."""
    fields = _fields(model)
    found: dict[str | None, str] = {}
    missing: list[tuple[str | None, str]] = []
    for detail in error.errors():
        key = str(detail["loc"][0]) if detail["loc"] else None
        if detail["type"] == "missing":
            if key not in deferred:
                missing.append((key, f"missing parameter {key!r}"))
        elif key in found:
            continue  # one message a parameter (a union fails once per option)
        elif detail["type"] == "extra_forbidden":
            found[key] = f"unknown parameter {key!r} ({', '.join(fields.names)})"
        elif key is None or key not in values:
            found[key] = detail["msg"]  # a check across parameters
        else:
            value = values[key]
            found[key] = (
                f"parameter {key!r} must be {fields.expected[key]}, "
                f"not {type(value).__name__} {_short(value)}"
            )
    order = {key: index for index, key in enumerate(values)}
    written = sorted(found.items(), key=lambda item: order.get(item[0] or "", len(order)))
    return [*written, *missing]


def holds_placeholder(value: Any) -> bool:
    """A value to bind when the state is entered: a placeholder in it, at any depth."""
    if isinstance(value, str):
        return has_placeholder(value)
    if isinstance(value, list):
        return any(holds_placeholder(item) for item in value)
    if isinstance(value, dict):
        return any(holds_placeholder(item) for item in value.values())
    return False


def param_problems(
    model: type[BlockParams], written: Mapping[str, Any]
) -> list[tuple[str | None, str]]:
    """What is wrong with parameters as written in a file: ``(parameter, message)``.

    A value that is exactly one placeholder may be of any type (where the model lets
    it be bound): it is left out here and checked once bound. Other values must fit
    exactly (strict: ``"3"`` is not a number, ``3.5`` not a string), as the JSON Schema
    says.
    """
    deferred = frozenset(
        k for k, v in written.items() if model.may_bind(k) and is_single_placeholder(v)
    )
    values = {k: v for k, v in written.items() if k not in deferred}
    try:
        model.model_validate(values, strict=True)
    except ValidationError as error:
        return _explain(model, error, values, deferred)
    return []


_BROKEN = frozenset({CommandStatus.FAILED, CommandStatus.TIMED_OUT})
"""What a command ends with when the robot could not do it: the block fails."""

P = TypeVar("P", bound=BlockParams)


class Block(Node, Generic[P]):
    """A leaf state: binds its parameters on entry, sends robot commands, waits on them.

    ``PARAMS`` is the model of the parameters a file writes; ``self.args`` holds this
    entry's values, an instance of ``P`` (the same model, but for ``menu``, which asks
    an ``ask`` question made of its own parameters).
    """

    kind = "block"
    PARAMS: ClassVar[type[BlockParams]] = BlockParams
    OUTCOMES: ClassVar[tuple[str, ...]] = ("done",)
    DOC: ClassVar[str] = ""

    args: P
    """The parameters of this entry, bound and validated (set by :meth:`bind_params`)."""

    def __init__(self, name: str, rt: Runtime, params: Mapping[str, Any], io: Io | None = None):
        super().__init__(name, self.outcomes_for(params), rt, io)
        self.params = dict(params)
        self.handles: list[CommandHandle] = []
        self._templated = {k: v for k, v in self.params.items() if holds_placeholder(v)}
        """The values to bind at each entry; the others are the same every time."""
        self._fixed: BlockParams | None = None

    @classmethod
    def outcomes_for(cls, params: Mapping[str, Any]) -> tuple[str, ...]:
        """The outcomes of a state of this block with ``params`` as written (most
        blocks: fixed). Called at load, before placeholders are bound."""
        return cls.OUTCOMES

    def describe(self) -> dict[str, Any]:
        out = super().describe()
        out["kind"] = self.block_name
        out["params"] = self.params
        return out

    @property
    def block_name(self) -> str:
        return next((name for name, cls in BLOCKS.items() if cls is type(self)), "block")

    # ------------------------------------------------------------ helpers

    def bound(self) -> BlockParams:
        """The parameters of this entry as a ``PARAMS`` instance.

        Without placeholders: validated once (the loader checked them) and reused.
        With: bound in the current userdata and profiles, then validated in lax mode
        (``"3"`` is 3) with :data:`Text` values read as text; a value that does not
        fit raises :class:`BehaviorError`, which fails the activity.
        """
        model = self.PARAMS
        if not self._templated:
            if self._fixed is None:
                self._fixed = model.model_validate(self.params)
            return self._fixed
        fields = _fields(model)
        resolve = self.rt.resolver(self.ud)
        values = dict(self.params)
        for key, raw in self._templated.items():
            value = render(raw, resolve)
            if value is None or (value == "" and key not in fields.text):
                if key in fields.required:
                    values[key] = None
                else:
                    del values[key]  # bound to nothing: the default
            else:
                values[key] = value
        try:
            return model.model_validate(values, context=_BINDING)
        except ValidationError as error:
            where, message = _explain(model, error, values)[0]
            raw = self._templated.get(where or "")
            source = f" (bound from {raw!r})" if raw is not None else ""
            raise BehaviorError(f"{self.block_name}: {message}{source}") from None

    def bind_params(self) -> None:
        """Set ``self.args`` for this entry (called by :meth:`initialise`)."""
        self.args = cast(P, self.bound())

    def command(
        self,
        channel: Channel,
        action: str,
        args: Mapping[str, Any],
        now: datetime,
        priority: Priority = Priority.NORMAL,
    ) -> CommandHandle:
        handle = self.rt.ctx.expression.request(
            self.rt.ctx.source, channel, action, args, now, priority=priority
        )
        self.handles.append(handle)
        return handle

    def withdraw(self, now: datetime) -> None:
        """Interrupt this block's commands that still run."""
        for handle in self.handles:
            if not handle.finished:
                self.rt.ctx.expression.interrupt(handle, now)
        self.handles = []

    def command_error(self) -> str | None:
        for handle in self.handles:
            if handle.status in _BROKEN:
                reason = handle.detail or handle.status.value
                return f"{handle.channel} {handle.action} {handle.status.value}: {reason}"
        return None

    def commands_done(self) -> bool:
        return all(handle.finished for handle in self.handles)

    def initialise(self, now: datetime) -> None:
        self.handles = []
        self.bind_params()
        self.begin(now)

    def begin(self, now: datetime) -> None:
        """Start the block's work (also on resume, to restart it)."""

    def terminate(self, now: datetime, new_status: Status) -> None:
        if new_status is Status.INVALID:
            self.withdraw(now)

    def on_pause(self, now: datetime) -> None:
        self.withdraw(now)

    def on_resume(self, now: datetime) -> None:
        self.begin(now)

    def update(self, now: datetime) -> Status:
        error = self.command_error()
        if error is not None:
            return self.fail(error)
        if self.commands_done():
            return self.finish(self.OUTCOMES[0])
        return Status.RUNNING

    def wake(self, now: datetime) -> Wake | None:
        """This ``update`` reads only its commands' statuses: it waits for one to end."""
        return self.waiting_on_commands() if self.updates_as(Block) else None

    def updates_as(self, owner: type[Block[Any]]) -> bool:
        """Whether this block's ``update`` is ``owner``'s, the one whose ``wake`` is being
        asked, and reads the commands as Block does: a subclass that changes either may
        read something else, and ticks every tick unless its own ``wake`` says otherwise."""
        kind = type(self)
        return (
            kind.update is owner.update
            and kind.command_error is Block.command_error
            and kind.commands_done is Block.commands_done
        )

    def waiting_on_commands(self) -> Wake | None:
        """Sleep until a command ends (unless a preemption waits): whether they ended,
        and how, is all that :meth:`update` reads of them."""
        if self._preempt_requested:
            return None
        return Wake(None, [handle for handle in self.handles if not handle.finished])


class Countdown:
    """A deadline that survives a pause: the time left is kept while paused and runs
    on after it. Without seconds it never ends (the state waits to be cancelled)."""

    def __init__(self, now: datetime, seconds: float | None) -> None:
        self.deadline = now + timedelta(seconds=seconds) if seconds is not None else None
        self.remaining: float | None = None

    def pause(self, now: datetime) -> None:
        if self.deadline is not None:
            self.remaining = max(0.0, (self.deadline - now).total_seconds())

    def resume(self, now: datetime) -> None:
        if self.remaining is not None:
            self.deadline = now + timedelta(seconds=self.remaining)
            self.remaining = None

    def over(self, now: datetime) -> bool:
        return self.deadline is not None and now >= self.deadline


# ---------------------------------------------------------------- expression blocks

VOLUMES = {"quiet": 40, "soft": 40, "normal": 60, "loud": 80, "very_loud": 95}


def voice_settings(rt: Runtime) -> dict[str, int]:
    """The ``VoiceSettings`` rule's ``volume`` (``volume:NN``, ``quiet``, ``normal``,
    ``loud``) and ``rate_wpm`` (``rate:WPM``), for the robot's speech; empty without it."""
    rules = rt.ctx.rules
    if rules is None:
        return {}
    result = rules.evaluate("VoiceSettings", rt.ctx.params())
    if result is None:
        return {}
    settings: dict[str, int] = {}
    for activation in result.activate:
        name = str(activation).strip().lower()
        if name in VOLUMES:
            settings.setdefault("volume", VOLUMES[name])
        elif match := re.fullmatch(r"volume[:=\s]*(\d{1,3})", name):
            settings.setdefault("volume", min(100, int(match.group(1))))
        elif match := re.fullmatch(r"rate[:=\s]*(\d{2,3})", name):
            settings.setdefault("rate_wpm", min(400, max(40, int(match.group(1)))))
    return settings


def voice_volume(rt: Runtime) -> int | None:
    """The volume the ``VoiceSettings`` rule asks for, if any."""
    return voice_settings(rt).get("volume")


def speech_args(rt: Runtime, text: str, volume: float | None) -> dict[str, Any]:
    args: dict[str, Any] = {"text": text, **voice_settings(rt)}
    if volume is not None:
        args["volume"] = int(volume)
    return args


class SpeakParams(BlockParams):
    text: Text = Field(description="What to say; may use placeholders.")
    priority: Literal["normal", "high"] = Field(
        "normal", description="high: said before what else is queued."
    )
    volume: float | None = Field(
        None, description="0-100; by default the VoiceSettings rule decides."
    )


class Speak(Block[SpeakParams]):
    DOC = "Say a sentence; done when the robot has said it."
    PARAMS = SpeakParams

    def begin(self, now: datetime) -> None:
        self.handles = []
        priority = Priority.HIGH if self.args.priority == "high" else Priority.NORMAL
        args = speech_args(self.rt, self.args.text, self.args.volume)
        self.command("speech", "say", args, now, priority)


class ShowParams(BlockParams):
    text: Text = Field("", description="Text to show.")
    image: Text | None = Field(None, description="An image file to show.")
    face: str | None = Field(
        None, description="A face for the screen eyes: happy, closed_eyes, ..."
    )


class Show(Block[ShowParams]):
    DOC = "Show text, an image or a face on the screen."
    PARAMS = ShowParams

    def begin(self, now: datetime) -> None:
        self.handles = []
        args = {k: v for k, v in dict(self.args).items() if v not in (None, "")}
        self.command("screen", "show", args, now)


class GestureParams(BlockParams):
    name: str = Field(description="nod, wave, bow, dance_step, ...")
    duration_s: float | None = Field(None, description="By default the gesture's own.")
    toward: str | None = Field(
        None,
        description="A frame to make it toward (user, face:<id>, object:<name>): the hip "
        "turns to it first and follows it while the gesture lasts (seed 002's task frames).",
    )


TOWARD_DEAD_BAND_RAD = 0.06
"""A gesture made toward a frame turns again only when the frame moved more than this."""


class Gesture(Block[GestureParams]):
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
        located = locate(self.rt.ctx, frame, now)
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


class LedsParams(BlockParams):
    color: str = Field(description="A colour name or #rrggbb.")
    pattern: str = Field("solid", description="solid, blink, breathe, ...")


class Leds(Block[LedsParams]):
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
    DOC = "Play a song, video or photo album from local media; done when it ends."
    PARAMS = PlayMediaParams

    def begin(self, now: datetime) -> None:
        self.handles = []
        args = {k: v for k, v in dict(self.args).items() if v is not None}
        self.command("media", "play", args, now)


# ---------------------------------------------------------------- time and events


class WaitParams(BlockParams):
    seconds: float | None = Field(None, description="How long; null: until cancelled.")


class Wait(Block[WaitParams]):
    DOC = "Wait some seconds (null: until cancelled); the time left survives a pause."
    PARAMS = WaitParams

    def begin(self, now: datetime) -> None:
        self.countdown = Countdown(now, self.args.seconds)

    def on_pause(self, now: datetime) -> None:
        self.countdown.pause(now)

    def on_resume(self, now: datetime) -> None:
        self.countdown.resume(now)

    def update(self, now: datetime) -> Status:
        if self.countdown.over(now):
            return self.finish("done")
        return Status.RUNNING

    def wake(self, now: datetime) -> Wake | None:
        if self._preempt_requested or not self.updates_as(Wait):
            return None
        return Wake(self.countdown.deadline)  # ``over`` is ``now >= deadline``


class WaitEventParams(BlockParams):
    touch: list[str] = Field([], description="Touched parts that end the wait.")
    keywords: list[str] = Field([], description="Words or phrases said that end it.")
    screen: list[str] = Field([], description="Screen choices that end it.")
    timeout_s: float | None = Field(None, description="Then the outcome is timeout.")
    key: str | None = Field(None, description="Userdata key that receives what happened.")


class WaitEvent(Block[WaitEventParams]):
    DOC = "Wait for a touch, a spoken keyword or a screen choice (or a timeout)."
    OUTCOMES = ("event", "timeout")
    PARAMS = WaitEventParams

    def begin(self, now: datetime) -> None:
        self.countdown = Countdown(now, self.args.timeout_s)
        self.got: str | None = None

    def on_pause(self, now: datetime) -> None:
        self.countdown.pause(now)

    def on_resume(self, now: datetime) -> None:
        self.countdown.resume(now)

    def on_event(self, event: Event) -> bool:
        if self.got is not None:
            return False
        if isinstance(event, Touch) and event.part in self.args.touch:
            self.got = event.part
        elif isinstance(event, ScreenChoice):
            wanted = {s.lower() for s in self.args.screen}
            if event.choice.strip().lower() in wanted:
                self.got = event.choice
        elif isinstance(event, Speech):
            spoken = _words(event.text)
            hit = next((k for k in self.args.keywords if _words(k) in spoken), None)
            self.got = hit
        return self.got is not None

    def update(self, now: datetime) -> Status:
        if self.got is not None:
            if self.args.key:
                self.ud[self.args.key] = self.got
            return self.finish("event")
        if self.countdown.over(now):
            return self.finish("timeout")
        return Status.RUNNING

    def wake(self, now: datetime) -> Wake | None:
        """It waits for its timeout, or for an event it takes (taking one wakes it)."""
        if self._preempt_requested or not self.updates_as(WaitEvent):
            return None
        return Wake(self.countdown.deadline)


def _words(text: str) -> str:
    return " " + " ".join(re.findall(r"[\w']+", text.lower())) + " "


def match_answer(text: str, choices: Sequence[str]) -> str | None:
    """The choice ``text`` names (the longest one said as whole words), else None."""
    spoken = f" {digits(_words(text))} "  # "six" answers "6"
    best: str | None = None
    for choice in choices:
        wanted = _words(choice)
        if wanted.strip() and wanted in spoken and (best is None or len(choice) > len(best)):
            best = choice
    return best


class AskParams(BlockParams):
    question: Text = Field(description="What is asked (said, and shown with its choices).")
    choices: list[Text] = Field([], description="The answers taken; none: any answer.")
    correct: Text | None = Field(
        None, description="The right choice: the outcome is then correct or wrong."
    )
    branch: bool = Field(False, description="true: the outcome is the choice itself.")
    timeout_s: float = Field(12.0, description="Asked again after this long without answer.")
    attempts: int = Field(2, description="How many times it is asked at most.")
    key: str = Field("answer", description="Userdata key that receives the answer.")
    retry_text: Text = Field(
        "Sorry, I did not get that.", description="Said before asking again when misheard."
    )


class Ask(Block[AskParams]):
    DOC = (
        "Ask a question (said, and shown with its choices); take the answer by speech or "
        "screen; re-ask after a timeout, up to `attempts` times. With `correct`, the outcome "
        "says whether the answer was right; with `branch`, the outcome is the choice."
    )
    PARAMS: ClassVar[type[BlockParams]] = AskParams

    @classmethod
    def outcomes_for(cls, params: Mapping[str, Any]) -> tuple[str, ...]:
        choices = params.get("choices")
        if params.get("branch") is True and isinstance(choices, list):
            return (*[str(c) for c in choices], "no_answer")
        if params.get("correct") is not None:
            return ("correct", "wrong", "no_answer")
        return ("answered", "no_answer")

    def initialise(self, now: datetime) -> None:
        self.attempt = 0
        self.answer: str | None = None
        self.misheard = False
        super().initialise(now)

    def prompt(self) -> str:
        return self.args.question

    def choices(self) -> list[str]:
        return list(self.args.choices)

    def begin(self, now: datetime) -> None:
        self.withdraw(now)
        self.attempt += 1
        self.deadline: datetime | None = None
        text = self.prompt()
        if self.misheard:
            text = f"{self.args.retry_text} {text}"
            self.misheard = False
        if self.choices() and self.rt.ctx.params().get("user", {}).get("interaction_style") == (
            "screen"
        ):
            text = f"{text} Please answer on the screen."  # Table 2: voice did not work for them
        self.said = self.command("speech", "say", speech_args(self.rt, text, None), now)
        if self.choices():
            self.command("screen", "show", {"text": self.prompt(), "choices": self.choices()}, now)

    def on_pause(self, now: datetime) -> None:
        self.attempt -= 1  # the interrupted question is asked again, not counted twice
        super().on_pause(now)

    def interpret(self, event: Event) -> str | None:
        choices = self.choices()
        if isinstance(event, ScreenChoice):
            if not choices:
                return event.choice
            return next((c for c in choices if c.lower() == event.choice.strip().lower()), None)
        if isinstance(event, Speech):
            return match_answer(event.text, choices) if choices else event.text.strip() or None
        return None

    def on_event(self, event: Event) -> bool:
        if self.answer is not None or isinstance(event, Touch):
            return False
        answer = self.interpret(event)
        if answer is None:
            if isinstance(event, Speech) and match_activity(event.text) is not None:
                return False  # a request for another activity: the controller's
            self.misheard = True
            return True
        self.answer = answer
        return True

    def update(self, now: datetime) -> Status:
        error = self.command_error()
        if error is not None:
            return self.fail(error)
        if self.answer is not None:
            self.withdraw(now)
            return self.finish(self.answered(self.answer))
        if self.deadline is None and self.said.finished:
            self.deadline = now + timedelta(seconds=self.args.timeout_s)
        timed_out = self.deadline is not None and now >= self.deadline
        if self.misheard or timed_out:
            if self.attempt >= self.args.attempts:
                self.withdraw(now)
                return self.finish("no_answer")
            self.begin(now)
        return Status.RUNNING

    def wake(self, now: datetime) -> Wake | None:
        """It waits for its commands (the question said, a failure), for its deadline to
        ask again, or for an answer it takes (taking one, or mishearing, wakes it)."""
        waiting = self.waiting_on_commands() if self.updates_as(Ask) else None
        return None if waiting is None else waiting.until(self.deadline)

    def answered(self, answer: str) -> str:
        self.ud[self.args.key] = answer
        if self.args.branch:
            return answer
        correct = self.args.correct
        if correct is not None:
            return "correct" if answer.strip().lower() == correct.lower() else "wrong"
        return "answered"


class MenuParams(BlockParams):
    title: Text = Field("What would you like to do?", description="The question asked.")
    options: list[str] = Field(
        list(USER_SELECTABLE), description="The activities offered (by their names)."
    )
    timeout_s: float = Field(20.0, description="Asked again after this long without answer.")
    attempts: int = Field(2, description="How many times it is asked at most.")
    key: str = Field("choice", description="Userdata key that receives the choice.")
    retry_text: Text = Field(
        "Sorry, which one?", description="Said before asking again when misheard."
    )


class Menu(Ask):
    DOC = (
        "Show the user-selectable activities and take the choice (screen, or saying an "
        "activity or a synonym); the chosen activity becomes the result's redirect. "
        '"You choose" (or "surprise me"...) declines: the user leaves the choice '
        "to the robot."
    )
    OUTCOMES = ("chosen", "declined", "no_answer")
    PARAMS = MenuParams

    @classmethod
    def outcomes_for(cls, params: Mapping[str, Any]) -> tuple[str, ...]:
        return cls.OUTCOMES

    def bind_params(self) -> None:
        """The menu is an ask question made of the menu's parameters."""
        menu = cast(MenuParams, self.bound())
        self.args = AskParams.model_construct(
            question=menu.title,
            choices=list(menu.options),
            timeout_s=menu.timeout_s,
            attempts=menu.attempts,
            key=menu.key,
            retry_text=menu.retry_text,
        )

    def interpret(self, event: Event) -> str | None:
        options = self.choices()
        if isinstance(event, ScreenChoice):
            text = event.choice.strip().lower()
            if text in options:
                return text
            named = match_activity(text)
        elif isinstance(event, Speech):
            text = event.text
            named = match_activity(text)
        else:
            return None
        if named is None and declines(text):
            return DECLINED
        return named if named in options else None

    def on_event(self, event: Event) -> bool:
        if self.answer is not None or isinstance(event, Touch):
            return False
        answer = self.interpret(event)
        if answer is None:
            self.misheard = isinstance(event, Speech)
            return self.misheard
        self.answer = answer
        return True

    def answered(self, answer: str) -> str:
        if answer == DECLINED:
            return "declined"
        self.ud[self.args.key] = answer
        self.rt.redirect = answer
        return "chosen"


DECLINED = "\x00declined"
"""The answer that leaves the choice to the robot (never an option's name)."""

_DECLINING = (
    "you choose",
    "you decide",
    "your choice",
    "surprise me",
    "you pick",
    "up to you",
    "whatever you like",
    "whatever you want",
    "i don't mind",
    "i don't know",
)


def declines(text: str) -> bool:
    """True if ``text`` leaves the choice to the robot ("you choose", "surprise me")."""
    folded = " ".join(text.lower().replace("’", "'").split())
    return any(phrase in folded for phrase in _DECLINING)


# ---------------------------------------------------------------- decisions and data


class DecideParams(BlockParams):
    component: str = Field(description="The DMSL component whose activation decides.")
    outcomes: list[str] = Field(description="The outcomes (activations taken).")
    default: str = Field("random", description="An outcome, or random.")


class Decide(Block[DecideParams]):
    DOC = (
        "Outcome = the first activation of a DMSL component that is one of `outcomes`; "
        "`default` (an outcome, or `random`) when no rule defines it or it activates none."
    )
    PARAMS = DecideParams

    @classmethod
    def outcomes_for(cls, params: Mapping[str, Any]) -> tuple[str, ...]:
        outcomes = params.get("outcomes")
        return tuple(str(o) for o in outcomes) if isinstance(outcomes, list) else ()

    def update(self, now: datetime) -> Status:
        outcomes = list(self.outcomes)
        rules = self.rt.ctx.rules
        result = (
            rules.evaluate(self.args.component, self.rt.ctx.params()) if rules is not None else None
        )
        if result is not None:
            for activation in result.activate:
                if activation in outcomes:
                    self.ud["decision"] = activation
                    return self.finish(activation)
        default = self.args.default
        choice = self.rt.ctx.rng.choice(outcomes) if default == "random" else default
        self.ud["decision"] = choice
        return self.finish(choice)


class SetParamParams(BlockParams):
    name: str = Field(description="The profile parameter.")
    value: Any = Field(description="Its new value.")


class SetParam(Block[SetParamParams]):
    DOC = "Store a value in the present user's profile."
    PARAMS = SetParamParams

    def update(self, now: datetime) -> Status:
        # a copy: the value as written is shared by every entry of the state
        self.rt.ctx.set_user_param(self.args.name, copy.deepcopy(self.args.value))
        return self.finish("done")


class SetDataParams(BlockParams):
    values: dict[str, Any] = Field({}, description="Keys set to these values.")
    add: dict[str, Any] = Field({}, description="Numbers added to these keys.")
    append: dict[str, Any] = Field({}, description="Values appended to these lists.")


class SetData(Block[SetDataParams]):
    DOC = "Change userdata: `values` sets keys, `add` adds numbers, `append` appends to lists."
    PARAMS = SetDataParams

    def update(self, now: datetime) -> Status:
        # copies: the values as written are shared by every entry of the state
        for key, value in self.args.values.items():
            self.ud[key] = copy.deepcopy(value)
        for key, amount in self.args.add.items():
            current = self.ud.get(key, 0)
            self.ud[key] = _number(current) + _number(amount)
        for key, value in self.args.append.items():
            self.ud[key] = [*list(self.ud.get(key, []) or []), copy.deepcopy(value)]
        return self.finish("done")


def _number(value: Any) -> float | int:
    if isinstance(value, int | float) and not isinstance(value, bool):
        return value
    try:
        return int(str(value))
    except ValueError:
        try:
            return float(str(value))
        except ValueError:
            return 0


class SampleParams(BlockParams):
    items: list[Any] | None = Field(
        None, description="A list, or a placeholder such as {content.quiz.questions}."
    )
    range: list[int] | None = Field(None, description="[first, last] instead of items.")
    count: int | None = Field(None, description="How many; null: all, shuffled.")
    key: str = Field(description="Userdata key that receives the list drawn.")


class Sample(Block[SampleParams]):
    DOC = "Draw `count` items at random (all, shuffled, when null) into userdata `key`."
    PARAMS = SampleParams

    def update(self, now: datetime) -> Status:
        span = self.args.range
        if span is not None and len(span) == 2:
            pool: list[Any] = list(range(span[0], span[1] + 1))
        else:
            pool = list(self.args.items or [])
        if not pool:
            return self.fail("nothing to draw from")
        count = self.args.count
        count = len(pool) if count is None else max(0, min(count, len(pool)))
        self.ud[self.args.key] = self.rt.ctx.rng.sample(pool, count)
        return self.finish("done")


class CheckParams(BlockParams):
    value: Any = Field(description="What is tested (usually a placeholder).")
    in_: Any = Field(None, alias="in", description="met if value is one of these.")
    all_in: Any = Field(None, description="met if every item of value is one of these.")
    equals: Any = Field(None, description="met if value equals this.")
    at_least: float | None = Field(None, description="met if value is at least this.")


class Check(Block[CheckParams]):
    DOC = "Test userdata: `value` in `in`, all of `value` in `all_in`, equal, or at least."
    OUTCOMES = ("met", "not_met")
    PARAMS = CheckParams

    def update(self, now: datetime) -> Status:
        args = self.args
        value = args.value
        tests: list[Callable[[], bool]] = []
        if args.in_ is not None:
            tests.append(lambda: _norm(value) in [_norm(v) for v in _list(args.in_)])
        if args.all_in is not None:
            among = {_norm(v) for v in _list(args.all_in)}
            tests.append(lambda: all(_norm(v) in among for v in _list(value)))
        if args.equals is not None:
            tests.append(lambda: _norm(value) == _norm(args.equals))
        if args.at_least is not None:
            at_least = args.at_least
            tests.append(lambda: _number(value) >= at_least)
        return self.finish("met" if all(test() for test in tests) else "not_met")


def _list(value: Any) -> list[Any]:
    return list(value) if isinstance(value, list | tuple) else [value]


def _norm(value: Any) -> str:
    return as_text(value).strip().lower()


# ---------------------------------------------------------------- gaze and pointing


class AimParams(BlockParams):
    frame: str = Field(
        USER, description="What to aim at: user (whoever is in front), face:<id>, object:<name>."
    )
    last_known: bool = Field(
        True,
        description="Not seen now: aim where it was last seen (seed 002's task frames); "
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
        located = locate(self.rt.ctx, self.args.frame, now)
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


BLOCKS: dict[str, type[Block[Any]]] = {
    "speak": Speak,
    "ask": Ask,
    "show": Show,
    "menu": Menu,
    "gesture": Gesture,
    "leds": Leds,
    "play_media": PlayMedia,
    "wait": Wait,
    "wait_event": WaitEvent,
    "decide": Decide,
    "set_param": SetParam,
    "set_data": SetData,
    "sample": Sample,
    "check": Check,
    "look_at": LookAt,
    "point_at": PointAt,
    "attend": Attend,
}
"""Every leaf block by the name used in behavior files."""
