"""The building blocks for Mini: generic, parameterized leaf states (ROS Commander's tools).

Each block declares its parameters (:class:`Param`: type, default, whether required)
and its outcomes; the loader checks a behavior file against them and the JSON Schema
is generated from them. Parameter values may hold placeholders (``"{user.name}"``)
bound when the state is entered. Blocks that talk to the robot go through the
expression arbiter with the activity's source; a command that fails or is never
acknowledged fails the block (and the activity) with the reason.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from datetime import datetime, timedelta
from typing import Any, ClassVar

from activities.engine import Event, Io, Node, Runtime, Status
from activities.synonyms import match_activity
from activities.template import as_text, is_single_placeholder
from dms.kernel.activity_names import USER_SELECTABLE
from dms.kernel.expression import CommandHandle, CommandStatus, Priority
from dms.kernel.messages import Channel, ScreenChoice, Speech, Touch
from dms.kernel.words import digits


@dataclass(frozen=True)
class Param:
    """One parameter of a block."""

    type: str
    """``string``, ``integer``, ``number``, ``boolean``, ``string_list``, ``list``,
    ``mapping`` or ``any``; a ``"{...}"`` placeholder is accepted for any type."""
    required: bool = False
    default: Any = None
    doc: str = ""
    enum: tuple[str, ...] = ()
    nullable: bool = False


_BROKEN = frozenset({CommandStatus.FAILED, CommandStatus.TIMED_OUT})
"""What a command ends with when the robot could not do it: the block fails."""


class Block(Node):
    """A leaf state: binds its parameters on entry, sends robot commands, waits on them."""

    kind = "block"
    PARAMS: ClassVar[dict[str, Param]] = {}
    OUTCOMES: ClassVar[tuple[str, ...]] = ("done",)
    DOC: ClassVar[str] = ""

    def __init__(self, name: str, rt: Runtime, params: Mapping[str, Any], io: Io | None = None):
        super().__init__(name, self.outcomes_for(params), rt, io)
        self.params = dict(params)
        self.args: dict[str, Any] = {}
        self.handles: list[CommandHandle] = []

    @classmethod
    def outcomes_for(cls, params: Mapping[str, Any]) -> tuple[str, ...]:
        """The outcomes of a state of this block with ``params`` (most blocks: fixed)."""
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

    def bind_params(self) -> None:
        values: dict[str, Any] = {}
        for key, spec in self.PARAMS.items():
            raw = self.params.get(key, spec.default)
            values[key] = coerce(self.rt.render(raw, self.ud), spec)
        self.args = values

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


def coerce(value: Any, spec: Param) -> Any:
    """A bound value as the parameter's type (placeholders bind to text)."""
    if value is None or (value == "" and spec.type != "string"):
        return spec.default if value is None or spec.type != "string" else value
    try:
        if spec.type == "integer" and not isinstance(value, bool):
            return int(value)
        if spec.type == "number" and not isinstance(value, bool):
            return float(value)
    except (TypeError, ValueError):
        return spec.default
    if spec.type == "string" and not isinstance(value, str):
        return as_text(value)
    if spec.type == "string_list" and isinstance(value, list):
        return [as_text(item) for item in value]
    return value


def type_ok(value: Any, spec: Param) -> bool:
    """Whether a value written in a file fits the parameter's type."""
    if value is None:
        return spec.nullable or not spec.required
    if is_single_placeholder(value):
        return True
    match spec.type:
        case "string":
            ok = isinstance(value, str)
            return ok and (not spec.enum or value in spec.enum)
        case "integer":
            return isinstance(value, int) and not isinstance(value, bool)
        case "number":
            return isinstance(value, int | float) and not isinstance(value, bool)
        case "boolean":
            return isinstance(value, bool)
        case "string_list":
            return isinstance(value, list) and all(isinstance(v, str) for v in value)
        case "list":
            return isinstance(value, list)
        case "mapping":
            return isinstance(value, dict)
    return True


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


class Speak(Block):
    DOC = "Say a sentence; done when the robot has said it."
    PARAMS: ClassVar[dict[str, Param]] = {
        "text": Param("string", required=True, doc="What to say; may use placeholders."),
        "priority": Param("string", default="normal", enum=("normal", "high")),
        "volume": Param("number", doc="0-100; by default the VoiceSettings rule decides."),
    }

    def begin(self, now: datetime) -> None:
        self.handles = []
        priority = Priority.HIGH if self.args["priority"] == "high" else Priority.NORMAL
        args = speech_args(self.rt, self.args["text"], self.args["volume"])
        self.command("speech", "say", args, now, priority)


class Show(Block):
    DOC = "Show text, an image or a face on the screen."
    PARAMS: ClassVar[dict[str, Param]] = {
        "text": Param("string", default=""),
        "image": Param("string"),
        "face": Param("string", doc="A face for the screen eyes: happy, closed_eyes, ..."),
    }

    def begin(self, now: datetime) -> None:
        self.handles = []
        args = {k: v for k, v in self.args.items() if v not in (None, "")}
        self.command("screen", "show", args, now)


class Gesture(Block):
    DOC = "Move: nod, wave, bow, dance_step, ... (durations are the robot's)."
    PARAMS: ClassVar[dict[str, Param]] = {
        "name": Param("string", required=True),
        "duration_s": Param("number"),
    }

    def begin(self, now: datetime) -> None:
        self.handles = []
        args: dict[str, Any] = {"name": self.args["name"]}
        if self.args["duration_s"] is not None:
            args["duration_s"] = self.args["duration_s"]
        self.command("motion", "gesture", args, now)


class Leds(Block):
    DOC = "Set the cheek and heart LEDs."
    PARAMS: ClassVar[dict[str, Param]] = {
        "color": Param("string", required=True),
        "pattern": Param("string", default="solid"),
    }

    def begin(self, now: datetime) -> None:
        self.handles = []
        self.command("led", "set", dict(self.args), now)


class PlayMedia(Block):
    DOC = "Play a song, video or photo album from local media; done when it ends."
    PARAMS: ClassVar[dict[str, Param]] = {
        "title": Param("string", required=True),
        "file": Param("string"),
        "kind": Param("string", default="music", enum=("music", "video", "audio", "photos")),
        "duration_s": Param("number", default=60.0),
    }

    def begin(self, now: datetime) -> None:
        self.handles = []
        args = {k: v for k, v in self.args.items() if v is not None}
        self.command("media", "play", args, now)


# ---------------------------------------------------------------- time and events


class Wait(Block):
    DOC = "Wait some seconds (null: until cancelled); the time left survives a pause."
    PARAMS: ClassVar[dict[str, Param]] = {"seconds": Param("number", nullable=True)}

    def begin(self, now: datetime) -> None:
        seconds = self.args["seconds"]
        self.deadline = now + timedelta(seconds=seconds) if seconds is not None else None
        self.remaining: float | None = None

    def on_pause(self, now: datetime) -> None:
        if self.deadline is not None:
            self.remaining = max(0.0, (self.deadline - now).total_seconds())

    def on_resume(self, now: datetime) -> None:
        if self.remaining is not None:
            self.deadline = now + timedelta(seconds=self.remaining)
            self.remaining = None

    def update(self, now: datetime) -> Status:
        if self.deadline is not None and now >= self.deadline:
            return self.finish("done")
        return Status.RUNNING


class WaitEvent(Wait):
    DOC = "Wait for a touch, a spoken keyword or a screen choice (or a timeout)."
    OUTCOMES = ("event", "timeout")
    PARAMS: ClassVar[dict[str, Param]] = {
        "touch": Param("string_list", default=[]),
        "keywords": Param("string_list", default=[]),
        "screen": Param("string_list", default=[]),
        "timeout_s": Param("number", nullable=True),
        "key": Param("string", doc="Userdata key that receives what happened."),
    }

    def begin(self, now: datetime) -> None:
        self.args["seconds"] = self.args["timeout_s"]
        super().begin(now)
        self.got: str | None = None

    def on_event(self, event: Event) -> bool:
        if self.got is not None:
            return False
        if isinstance(event, Touch) and event.part in self.args["touch"]:
            self.got = event.part
        elif isinstance(event, ScreenChoice):
            wanted = {s.lower() for s in self.args["screen"]}
            if event.choice.strip().lower() in wanted:
                self.got = event.choice
        elif isinstance(event, Speech):
            spoken = _words(event.text)
            hit = next((k for k in self.args["keywords"] if _words(k) in spoken), None)
            self.got = hit
        return self.got is not None

    def update(self, now: datetime) -> Status:
        if self.got is not None:
            if self.args["key"]:
                self.ud[self.args["key"]] = self.got
            return self.finish("event")
        if super().update(now) is Status.DONE:
            return self.finish("timeout")
        return Status.RUNNING


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


class Ask(Block):
    DOC = (
        "Ask a question (said, and shown with its choices); take the answer by speech or "
        "screen; re-ask after a timeout, up to `attempts` times. With `correct`, the outcome "
        "says whether the answer was right; with `branch`, the outcome is the choice."
    )
    PARAMS: ClassVar[dict[str, Param]] = {
        "question": Param("string", required=True),
        "choices": Param("string_list", default=[]),
        "correct": Param("string"),
        "branch": Param("boolean", default=False),
        "timeout_s": Param("number", default=12.0),
        "attempts": Param("integer", default=2),
        "key": Param("string", default="answer", doc="Userdata key that receives the answer."),
        "retry_text": Param("string", default="Sorry, I did not get that."),
    }

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
        return str(self.args["question"])

    def choices(self) -> list[str]:
        return list(self.args["choices"] or [])

    def begin(self, now: datetime) -> None:
        self.withdraw(now)
        self.attempt += 1
        self.deadline: datetime | None = None
        text = self.prompt()
        if self.misheard:
            text = f"{self.args['retry_text']} {text}"
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
            self.deadline = now + timedelta(seconds=float(self.args["timeout_s"]))
        timed_out = self.deadline is not None and now >= self.deadline
        if self.misheard or timed_out:
            if self.attempt >= int(self.args["attempts"]):
                self.withdraw(now)
                return self.finish("no_answer")
            self.begin(now)
        return Status.RUNNING

    def answered(self, answer: str) -> str:
        self.ud[self.args["key"]] = answer
        if self.args["branch"]:
            return answer
        correct = self.args["correct"]
        if correct is not None:
            return "correct" if answer.strip().lower() == str(correct).lower() else "wrong"
        return "answered"


class Menu(Ask):
    DOC = (
        "Show the user-selectable activities and take the choice (screen, or saying an "
        "activity or a synonym); the chosen activity becomes the result's redirect. "
        '"You choose" (or "surprise me"...) declines: the user leaves the choice '
        "to the robot."
    )
    OUTCOMES = ("chosen", "declined", "no_answer")
    PARAMS: ClassVar[dict[str, Param]] = {
        "title": Param("string", default="What would you like to do?"),
        "options": Param("string_list", default=list(USER_SELECTABLE)),
        "timeout_s": Param("number", default=20.0),
        "attempts": Param("integer", default=2),
        "key": Param("string", default="choice"),
        "retry_text": Param("string", default="Sorry, which one?"),
    }

    @classmethod
    def outcomes_for(cls, params: Mapping[str, Any]) -> tuple[str, ...]:
        return cls.OUTCOMES

    def bind_params(self) -> None:
        super().bind_params()
        self.args["question"] = self.args["title"]
        self.args["choices"] = self.args["options"]
        self.args["branch"] = False
        self.args["correct"] = None

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
        self.ud[self.args["key"]] = answer
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


class Decide(Block):
    DOC = (
        "Outcome = the first activation of a DMSL component that is one of `outcomes`; "
        "`default` (an outcome, or `random`) when no rule defines it or it activates none."
    )
    PARAMS: ClassVar[dict[str, Param]] = {
        "component": Param("string", required=True),
        "outcomes": Param("string_list", required=True),
        "default": Param("string", default="random"),
    }

    @classmethod
    def outcomes_for(cls, params: Mapping[str, Any]) -> tuple[str, ...]:
        outcomes = params.get("outcomes")
        return tuple(str(o) for o in outcomes) if isinstance(outcomes, list) else ()

    def update(self, now: datetime) -> Status:
        outcomes = list(self.outcomes)
        rules = self.rt.ctx.rules
        result = (
            rules.evaluate(self.args["component"], self.rt.ctx.params())
            if rules is not None
            else None
        )
        if result is not None:
            for activation in result.activate:
                if activation in outcomes:
                    self.ud["decision"] = activation
                    return self.finish(activation)
        default = self.args["default"]
        choice = self.rt.ctx.rng.choice(outcomes) if default == "random" else default
        self.ud["decision"] = choice
        return self.finish(choice)


class SetParam(Block):
    DOC = "Store a value in the present user's profile."
    PARAMS: ClassVar[dict[str, Param]] = {
        "name": Param("string", required=True),
        "value": Param("any", required=True),
    }

    def update(self, now: datetime) -> Status:
        self.rt.ctx.set_user_param(self.args["name"], self.args["value"])
        return self.finish("done")


class SetData(Block):
    DOC = "Change userdata: `values` sets keys, `add` adds numbers, `append` appends to lists."
    PARAMS: ClassVar[dict[str, Param]] = {
        "values": Param("mapping", default={}),
        "add": Param("mapping", default={}),
        "append": Param("mapping", default={}),
    }

    def update(self, now: datetime) -> Status:
        for key, value in (self.args["values"] or {}).items():
            self.ud[key] = value
        for key, amount in (self.args["add"] or {}).items():
            current = self.ud.get(key, 0)
            self.ud[key] = _number(current) + _number(amount)
        for key, value in (self.args["append"] or {}).items():
            self.ud[key] = [*list(self.ud.get(key, []) or []), value]
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


class Sample(Block):
    DOC = "Draw `count` items at random (all, shuffled, when null) into userdata `key`."
    PARAMS: ClassVar[dict[str, Param]] = {
        "items": Param("any", doc="A list, or a placeholder such as {content.quiz.questions}."),
        "range": Param("list", doc="[first, last] integers instead of items."),
        "count": Param("integer", nullable=True),
        "key": Param("string", required=True),
    }

    def update(self, now: datetime) -> Status:
        span = self.args["range"]
        if isinstance(span, list) and len(span) == 2:
            pool: list[Any] = list(range(int(span[0]), int(span[1]) + 1))
        else:
            items = self.args["items"]
            pool = list(items) if isinstance(items, list) else []
        if not pool:
            return self.fail("nothing to draw from")
        count = self.args["count"]
        count = len(pool) if count is None else max(0, min(int(count), len(pool)))
        self.ud[self.args["key"]] = self.rt.ctx.rng.sample(pool, count)
        return self.finish("done")


class Check(Block):
    DOC = "Test userdata: `value` in `in`, all of `value` in `all_in`, equal, or at least."
    OUTCOMES = ("met", "not_met")
    PARAMS: ClassVar[dict[str, Param]] = {
        "value": Param("any", required=True),
        "in": Param("any"),
        "all_in": Param("any"),
        "equals": Param("any"),
        "at_least": Param("number"),
    }

    def update(self, now: datetime) -> Status:
        value = self.args["value"]
        tests: list[Callable[[], bool]] = []
        if self.args["in"] is not None:
            tests.append(lambda: _norm(value) in [_norm(v) for v in _list(self.args["in"])])
        if self.args["all_in"] is not None:
            among = {_norm(v) for v in _list(self.args["all_in"])}
            tests.append(lambda: all(_norm(v) in among for v in _list(value)))
        if self.args["equals"] is not None:
            tests.append(lambda: _norm(value) == _norm(self.args["equals"]))
        if self.args["at_least"] is not None:
            tests.append(lambda: _number(value) >= float(self.args["at_least"]))
        return self.finish("met" if all(test() for test in tests) else "not_met")


def _list(value: Any) -> list[Any]:
    return list(value) if isinstance(value, list | tuple) else [value]


def _norm(value: Any) -> str:
    return as_text(value).strip().lower()


BLOCKS: dict[str, type[Block]] = {
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
}
"""Every leaf block by the name used in behavior files."""
