"""The open format: behavior files in YAML, checked on load, saved without loss.

Over 600 lines: the format's model, its parser and its structural checks read together.

A behavior file is a state machine::

    name: quiz
    description: ...
    outcomes: [done]
    initial: INTRO            # optional: the first state listed
    userdata: {score: 0}      # optional
    states:
      INTRO:
        speak: {text: "Hello {user.name|there}!"}
        transitions: {done: GAME}
      GAME:
        guard: {touch: [left_shoulder], outcome: touched, state: {...}}
        transitions: {done: END, touched: END}

Each state has exactly one block key (a building block of :mod:`activities.blocks`,
or a container: ``state_machine``, ``concurrence``, ``iterator``, ``guard``,
``behavior``) plus optional ``transitions``, ``input_keys``, ``output_keys`` and
``remapping``. Problems are reported as ``file:line: state PATH: message``.

The parameters of blocks and containers are pydantic models (:class:`BlockParams`, the
blocks' beside them in :mod:`activities.blocks`, the containers' here): the loader's
parameter checks and the JSON Schema (:mod:`activities.schema`) both come from them.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import yaml
from pydantic import Field

from activities.blocks import (
    BLOCKS,
    AttendParams,
    BlockParams,
    param_problems,
)
from activities.declaration import declaration_problems
from activities.engine import PREEMPTED
from activities.errors import BehaviorError
from activities.names import FRAME_PARAMS, frame_problem, value_problems
from activities.task_frames import TaskFrame, close_task_frame, parse_frames
from dms.kernel.yamlfile import Located, load_located, plain
from dms.kernel.yamlfile import line_of_key as _line

CONTAINERS = ("state_machine", "sequence", "concurrence", "iterator", "guard", "behavior")
MACHINES = ("state_machine", "sequence")
"""Containers whose states are joined by transitions (a sequence adds its own)."""
GROUPS = (*MACHINES, "concurrence")
"""Containers with a ``states`` mapping."""
STATE_KEYS = ("transitions", "input_keys", "output_keys", "remapping")
TOP_KEYS = (
    "name",
    "description",
    "activity",
    "attend",
    "frames",
    "outcomes",
    "initial",
    "userdata",
    "states",
)
AIMED = ("look_at", "point_at", "gesture")
"""The blocks that may aim at a task frame (they locate their frame each time)."""


class StateMachineParams(BlockParams):
    """A nested state machine."""

    PLACEHOLDERS = frozenset()

    outcomes: list[str] = Field(description="How the machine can end.")
    initial: str | None = Field(None, description="The first state; by default the first listed.")
    userdata: dict[str, Any] = Field({}, description="The machine's own userdata at start.")
    states: dict[str, Any] = Field(description="The states, by name.")


class SequenceParams(BlockParams):
    """States in the order written (SMACH's Sequence)."""

    PLACEHOLDERS = frozenset()

    outcomes: list[str] = Field(description="How the sequence can end.")
    connector_outcome: str = Field(description="The outcome that goes on to the next state.")
    userdata: dict[str, Any] = Field({}, description="The sequence's own userdata at start.")
    states: dict[str, Any] = Field(description="The states, in order.")


class ConcurrenceParams(BlockParams):
    """States ticked together."""

    PLACEHOLDERS = frozenset()

    outcomes: list[str] = Field(description="How the concurrence can end.")
    default_outcome: str = Field(description="When all have ended and no entry matched.")
    outcome_map: dict[str, Any] = Field(
        {}, description="outcome: {state: its outcome, ...}, read in order."
    )
    wait: Literal["match", "any", "all"] = Field(
        "match",
        description="When the other states are preempted: match (an outcome_map entry "
        "matched), any (a state ended) or all (never: SMACH's default).",
    )
    userdata: dict[str, Any] = Field({}, description="The concurrence's own userdata.")
    states: dict[str, Any] = Field(description="The states, by name.")


class IteratorParams(BlockParams):
    """One state run once per item."""

    PLACEHOLDERS = frozenset({"items"})

    items: list[Any] | int = Field(description="A list, a count, or a placeholder.")
    item_key: str = Field("item", description="Userdata key of the current item.")
    index_key: str | None = Field(None, description="Userdata key of its index, from 1.")
    continue_on: list[str] = Field(description="Outcomes that go on to the next item.")
    break_on: dict[str, str] = Field({}, description="Outcomes that end it: state's: ours.")
    exhausted: str = Field("done", description="The outcome after the last item.")
    state: dict[str, Any] = Field(description="The one state, by name.")


class GuardParams(BlockParams):
    """ROS Commander's tactile guard: a touch, a keyword, a screen choice or a timer
    ends the state inside with ``outcome``."""

    PLACEHOLDERS = frozenset()

    touch: list[str] = Field([], description="Touched parts that end it.")
    keywords: list[str] = Field([], description="Words or phrases said that end it.")
    screen: list[str] = Field([], description="Screen choices that end it.")
    timer_s: float | None = Field(None, description="Seconds after which it ends.")
    outcome: str = Field("triggered", description="The outcome then.")
    state: dict[str, Any] = Field(description="The one state guarded, by name.")


class BehaviorParams(BlockParams):
    """Another behavior file as a state."""

    PLACEHOLDERS = frozenset()

    name: str = Field(description="The behavior's name.")


CONTAINER_PARAMS: dict[str, type[BlockParams]] = {
    "state_machine": StateMachineParams,
    "sequence": SequenceParams,
    "concurrence": ConcurrenceParams,
    "iterator": IteratorParams,
    "guard": GuardParams,
    "behavior": BehaviorParams,
}


# ---------------------------------------------------------------- the model


@dataclass
class StateSpec:
    """One state as written: its block (or container) and how it connects."""

    name: str
    block: str
    params: dict[str, Any]
    """The block's parameters as written (containers: without their child states)."""
    transitions: dict[str, str] = field(default_factory=dict)
    input_keys: list[str] = field(default_factory=list)
    output_keys: list[str] = field(default_factory=list)
    remapping: dict[str, str] = field(default_factory=dict)
    states: dict[str, StateSpec] = field(default_factory=dict)
    """Child states of a state_machine/concurrence, or the one of an iterator/guard."""
    line: int = 0
    present: tuple[str, ...] = ()
    """Which optional keys the file had, so saving writes back exactly them."""
    transition_lines: dict[str, int] = field(default_factory=dict, compare=False, repr=False)
    param_lines: dict[str, int] = field(default_factory=dict, compare=False, repr=False)
    """The line of each parameter as written, for the messages of later checks."""

    def to_dict(self) -> dict[str, Any]:
        body = dict(self.params)
        if self.block in GROUPS:
            body["states"] = {name: s.to_dict() for name, s in self.states.items()}
        elif self.block in ("iterator", "guard"):
            body["state"] = {name: s.to_dict() for name, s in self.states.items()}
        out: dict[str, Any] = {self.block: body}
        for key in STATE_KEYS:
            if key in self.present:
                out[key] = getattr(self, key)
        return out

    def outcomes(self, library: Mapping[str, BehaviorSpec] | None = None) -> tuple[str, ...]:
        """The outcomes this state may end with (``preempted`` aside)."""
        if self.block in BLOCKS:
            return BLOCKS[self.block].outcomes_for(self.params)
        if self.block in GROUPS:
            return tuple(self.params.get("outcomes") or ())
        if self.block == "iterator":
            breaks = [str(v) for v in (self.params.get("break_on") or {}).values()]
            return tuple(dict.fromkeys([str(self.params.get("exhausted", "done")), *breaks]))
        if self.block == "guard":
            inner = [o for s in self.states.values() for o in s.outcomes(library)]
            return tuple(dict.fromkeys([*inner, str(self.params.get("outcome", "triggered"))]))
        if self.block == "behavior" and library is not None:
            target = library.get(str(self.params.get("name")))
            return tuple(target.outcomes) if target is not None else ()
        return ()


@dataclass
class BehaviorSpec:
    """A whole behavior file."""

    name: str
    root: StateSpec
    description: str | None = None
    path: Path | None = None
    present: tuple[str, ...] = ()
    attend: str | dict[str, Any] | None = None
    """``attend:`` at the top as written: the gaze kept on a frame while the behavior
    runs, a frame's name or :class:`activities.blocks.AttendParams`."""
    frames: dict[str, TaskFrame] = field(default_factory=dict)
    """``frames:`` at the top: the task frames its states may aim at, by name."""
    activity: dict[str, Any] | None = None
    """``activity:`` as written, checked: the behavior declared an activity
    (:mod:`activities.declaration`); None: a behavior only."""

    @property
    def outcomes(self) -> list[str]:
        return list(self.root.params.get("outcomes") or [])

    def attention(self) -> AttendParams | None:
        """The ``attend:`` settings, validated (the loader checked them)."""
        if self.attend is None:
            return None
        written = {"frame": self.attend} if isinstance(self.attend, str) else self.attend
        return AttendParams.model_validate(written)

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"name": self.name}
        if "description" in self.present:
            out["description"] = self.description
        if self.activity is not None:
            out["activity"] = self.activity
        if self.attend is not None:
            out["attend"] = self.attend
        if self.frames:
            out["frames"] = {name: frame.to_dict() for name, frame in self.frames.items()}
        out["outcomes"] = self.root.params.get("outcomes")
        for key in ("initial", "userdata"):
            if key in self.root.params:
                out[key] = self.root.params[key]
        out["states"] = {name: s.to_dict() for name, s in self.root.states.items()}
        return out

    def dump(self) -> str:
        """The behavior as YAML text."""
        return yaml.safe_dump(self.to_dict(), sort_keys=False, allow_unicode=True, width=100)

    def save(self, path: Path) -> None:
        path.write_text(self.dump(), encoding="utf-8")

    def references(self) -> set[str]:
        """The behaviors this one uses as states."""
        found: set[str] = set()

        def walk(state: StateSpec) -> None:
            if state.block == "behavior":
                found.add(str(state.params.get("name")))
            for child in state.states.values():
                walk(child)

        walk(self.root)
        return found


# ---------------------------------------------------------------- parsing and checking


class _Checker:
    def __init__(self, where: str) -> None:
        self.where = where
        self.problems: list[str] = []
        self.task_frames: frozenset[str] = frozenset()
        """The task frames the behavior declares: names its aiming states may use."""

    def problem(self, line: int, path: str, message: str) -> None:
        at = f"{self.where}:{line}" if line else self.where
        state = f" state {path}:" if path else ""
        self.problems.append(f"{at}:{state} {message}")


def parse_text(text: str, where: str, path: Path | None = None) -> BehaviorSpec:
    """Parse and check one behavior; raise BehaviorError naming file, line and state."""
    try:
        data = load_located(text)
    except yaml.YAMLError as error:
        mark = getattr(error, "problem_mark", None)
        line = f":{mark.line + 1}" if mark is not None else ""
        problem = getattr(error, "problem", None) or str(error).splitlines()[0]
        raise BehaviorError(f"{where}{line}: not valid YAML: {problem}") from None
    checker = _Checker(where)
    if not isinstance(data, Located):
        raise BehaviorError(f"{where}:1: a behavior file is a mapping with name and states")
    for key in data:
        if key not in TOP_KEYS:
            checker.problem(_line(data, key), "", f"unknown key {key!r}")
    name = data.get("name")
    if not isinstance(name, str) or not name:
        checker.problem(_line(data, "name"), "", "name must be a non-empty string")
        name = path.stem if path is not None else "behavior"
    description = data.get("description")
    if description is not None and not isinstance(description, str):
        checker.problem(_line(data, "description"), "", "description must be a string")
    attend = _parse_attend(checker, data)
    frames, frame_problems = parse_frames(plain(data.get("frames")))
    held = data.get("frames")
    for frame_name, problem in frame_problems:
        at = _line(held, frame_name) if isinstance(held, Located) and frame_name in held else 0
        checker.problem(at or _line(data, "frames"), "", problem)
    checker.task_frames = frozenset(frames)
    activity = _parse_activity(checker, data, name)
    body = {key: data[key] for key in ("outcomes", "initial", "userdata", "states") if key in data}
    located = Located(body)
    located.line, located.key_lines = data.line, data.key_lines
    root = _parse_state(checker, "", "state_machine", located, data.line)
    if root is not None:
        _check_machine(checker, root, "")
    if checker.problems:
        first = checker.problems[0]
        more = f" (and {len(checker.problems) - 1} more)" if len(checker.problems) > 1 else ""
        raise BehaviorError(first + more, checker.problems)
    assert root is not None
    present = tuple(k for k in ("description",) if k in data)
    return BehaviorSpec(name, root, description, path, present, attend, frames, activity)


def _parse_activity(checker: _Checker, data: Located, name: str) -> dict[str, Any] | None:
    """The top ``activity:``, each problem at its line (:mod:`activities.declaration`)."""
    if "activity" not in data:
        return None
    raw = data["activity"]
    for key, message in declaration_problems(name, raw):
        at = _line(raw, key) if key is not None and isinstance(raw, Located) else 0
        checker.problem(at or _line(data, "activity"), "", message)
    return dict(plain(raw)) if isinstance(raw, dict) else None


def _parse_attend(checker: _Checker, data: Located) -> str | dict[str, Any] | None:
    """The top ``attend:``: a frame's name, or the attend block's settings but ``seconds``."""
    if "attend" not in data:
        return None
    raw = data["attend"]
    line = _line(data, "attend")
    frame = raw.get("frame") if isinstance(raw, dict) else raw
    if isinstance(frame, str) and (problem := frame_problem(frame)) is not None:
        at = _line(raw, "frame") if isinstance(raw, Located) else line
        checker.problem(at, "", f"attend: {problem}")
    if isinstance(raw, str):
        return raw
    if not isinstance(raw, dict):
        checker.problem(line, "", "attend: must be a frame's name or a mapping")
        return None
    for key, message in param_problems(AttendParams, plain(raw)):
        at = _line(raw, key) if key in raw and isinstance(raw, Located) else line
        checker.problem(at, "", f"attend: {message}")
    return dict(plain(raw))


def parse_file(path: Path) -> BehaviorSpec:
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as error:
        raise BehaviorError(f"{path}: cannot read: {error}") from None
    return parse_text(text, str(path), path)


def _check_params(
    checker: _Checker,
    path: str,
    block: str,
    params: Any,
    model: type[BlockParams],
    line: int,
) -> dict[str, Any]:
    """The parameters as written, each problem the model finds reported at its line."""
    if params is None:
        params = {}
    if not isinstance(params, dict):
        checker.problem(line, path, f"{block}: parameters must be a mapping")
        return {}
    for key, message in param_problems(model, plain(params)):
        at = _line(params, key) if key in params else line
        checker.problem(at, path, f"{block}: {message}")
    return params


def _parse_state(
    checker: _Checker, path: str, block: str, params: Any, line: int
) -> StateSpec | None:
    """The block part of a state (params of a leaf, or a container with children)."""
    name = path.rsplit("/", 1)[-1]
    lines = dict(params.key_lines) if isinstance(params, Located) else {}
    if block in BLOCKS:
        checked = _check_params(checker, path, block, params, BLOCKS[block].PARAMS, line)
        for key, message in value_problems(block, checked):
            aims = block in AIMED and key == FRAME_PARAMS.get(block)
            if aims and checked.get(key) in checker.task_frames:
                continue
            meant = close_task_frame(checked.get(key), checker.task_frames) if aims else None
            if meant is not None:
                message = f"{block}: parameter {key!r}: no task frame {checked[key]!r}; {meant}"
            checker.problem(lines.get(key, line), path, message)
        return StateSpec(name, block, plain(checked), line=line, param_lines=lines)
    checked = _check_params(checker, path, block, params, CONTAINER_PARAMS[block], line)
    children: dict[str, StateSpec] = {}
    child_key = "states" if block in GROUPS else "state"
    raw_children = checked.get(child_key)
    if block != "behavior":
        if not isinstance(raw_children, dict) or not raw_children:
            checker.problem(line, path, f"{block}: {child_key} must name at least one state")
        elif child_key == "state" and len(raw_children) != 1:
            checker.problem(line, path, f"{block}: state must hold exactly one state")
        else:
            for child_name, child in raw_children.items():
                child_path = f"{path}/{child_name}" if path else str(child_name)
                spec = parse_state_entry(
                    checker, child_path, child, _line(raw_children, child_name)
                )
                if spec is not None:
                    children[str(child_name)] = spec
    own = {k: plain(v) for k, v in checked.items() if k != child_key}
    if block == "sequence":
        _connect(children, own.get("connector_outcome"))
    return StateSpec(name, block, own, states=children, line=line, param_lines=lines)


def _connect(children: Mapping[str, StateSpec], connector: Any) -> None:
    """A sequence: each state's connector outcome goes to the next one (SMACH's
    ``Sequence.add``); a transition written for it wins, the last one passes it up."""
    names = list(children)
    for name, following in itertools.pairwise(names):
        if isinstance(connector, str):
            children[name].transitions.setdefault(connector, following)


def parse_state_entry(checker: _Checker, path: str, raw: Any, line: int) -> StateSpec | None:
    """One entry of ``states``: exactly one block key plus the connection keys."""
    if not isinstance(raw, dict):
        checker.problem(line, path, "a state is a mapping with one block")
        return None
    kinds = [key for key in raw if key not in STATE_KEYS]
    unknown = [key for key in kinds if key not in BLOCKS and key not in CONTAINERS]
    for key in unknown:
        checker.problem(_line(raw, key), path, f"unknown block {key!r}")
    if unknown:
        return None
    if len(kinds) != 1:
        found = ", ".join(kinds) or "none"
        checker.problem(line, path, f"a state has exactly one block (found: {found})")
        return None
    block = kinds[0]
    spec = _parse_state(checker, path, block, raw[block], _line(raw, block))
    if spec is None:
        return None
    spec.line = line or _line(raw, block)
    present = []
    for key in STATE_KEYS:
        if key not in raw:
            continue
        present.append(key)
        value = raw[key]
        if key in ("transitions", "remapping"):
            if not isinstance(value, dict) or not all(isinstance(v, str) for v in value.values()):
                checker.problem(_line(raw, key), path, f"{key} must map names to names")
                continue
            setattr(spec, key, {str(k): v for k, v in value.items()})
        else:
            if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
                checker.problem(_line(raw, key), path, f"{key} must be a list of names")
                continue
            setattr(spec, key, list(value))
    spec.present = tuple(present)
    spec.name = path.rsplit("/", 1)[-1]
    raw_transitions = raw.get("transitions")
    if isinstance(raw_transitions, Located):
        spec.transition_lines = dict(raw_transitions.key_lines)
    return spec


def _check_machine(checker: _Checker, state: StateSpec, path: str) -> None:
    """Container rules: transitions, reachability, outcome maps; recursively."""
    prefix = f"{path}/" if path else ""
    if state.block in MACHINES:
        outcomes = set(state.params.get("outcomes") or [])
        names = list(state.states)
        initial = state.params.get("initial", names[0] if names else None)
        if initial is not None and initial not in state.states:
            checker.problem(state.line, path, f"initial state {initial!r} does not exist")
        for name, child in state.states.items():
            lines = child.transition_lines
            for outcome, target in child.transitions.items():
                line = lines.get(outcome, child.line)
                if target not in state.states and target not in outcomes:
                    checker.problem(
                        line,
                        prefix + name,
                        f"transition {outcome!r} goes to missing state {target!r}",
                    )
                declared = child.outcomes()
                if child.block != "behavior" and outcome not in declared and outcome != PREEMPTED:
                    checker.problem(
                        line,
                        prefix + name,
                        f"{child.block} has no outcome {outcome!r} (it has {list(declared)})",
                    )
            if child.block != "behavior":
                for outcome in child.outcomes():
                    if outcome not in child.transitions and outcome not in outcomes:
                        checker.problem(
                            child.line,
                            prefix + name,
                            f"outcome {outcome!r} leads nowhere (add a transition)",
                        )
        if initial in state.states:
            seen = {initial}
            todo = [initial]
            while todo:
                current = state.states[todo.pop()]
                for target in current.transitions.values():
                    if target in state.states and target not in seen:
                        seen.add(target)
                        todo.append(target)
            for name, child in state.states.items():
                if name not in seen:
                    checker.problem(child.line, prefix + name, "unreachable state")
    elif state.block == "concurrence":
        outcomes = set(state.params.get("outcomes") or [])
        default = state.params.get("default_outcome")
        if default not in outcomes:
            checker.problem(state.line, path, f"default_outcome {default!r} is not an outcome")
        omap = state.params.get("outcome_map") or {}
        for outcome, wanted in omap.items():
            if outcome not in outcomes:
                checker.problem(state.line, path, f"outcome_map: {outcome!r} is not an outcome")
            if not isinstance(wanted, dict):
                checker.problem(
                    state.line, path, f"outcome_map: {outcome!r} must map states to outcomes"
                )
                continue
            for child, child_outcome in wanted.items():
                if child not in state.states:
                    checker.problem(state.line, path, f"outcome_map: no state {child!r}")
                elif (
                    child_outcome not in (*state.states[child].outcomes(), PREEMPTED)
                    and state.states[child].block != "behavior"
                ):
                    checker.problem(
                        state.line, path, f"outcome_map: {child} has no outcome {child_outcome!r}"
                    )
        for name, child in state.states.items():
            if child.transitions:
                checker.problem(
                    child.line, prefix + name, "states of a concurrence have no transitions"
                )
    elif state.block == "iterator":
        continue_on = set(state.params.get("continue_on") or [])
        break_on = state.params.get("break_on") or {}
        for name, child in state.states.items():
            if child.block == "behavior":
                continue
            for outcome in child.outcomes():
                if outcome not in continue_on and outcome not in break_on:
                    checker.problem(
                        child.line,
                        prefix + name,
                        f"outcome {outcome!r} is neither in continue_on nor in break_on",
                    )
    for name, child in state.states.items():
        _check_machine(checker, child, prefix + name)


def check_references(specs: Mapping[str, BehaviorSpec]) -> list[str]:
    """Missing behaviors and cycles of behavior references, one problem per finding."""
    problems: list[str] = []

    def where(spec: BehaviorSpec, target: str) -> str:
        found: list[tuple[int, str]] = []

        def walk(state: StateSpec, path: str) -> None:
            for name, child in state.states.items():
                child_path = f"{path}/{name}" if path else name
                if child.block == "behavior" and child.params.get("name") == target:
                    found.append((child.line, child_path))
                walk(child, child_path)

        walk(spec.root, "")
        line, path = found[0] if found else (0, "")
        return f"{spec.path or spec.name}:{line}: state {path}:"

    for spec in specs.values():
        for target in sorted(spec.references()):
            if target not in specs:
                problems.append(f"{where(spec, target)} behavior {target!r} does not exist")
        problems.extend(_check_reference_outcomes(spec, specs))
    state: dict[str, int] = {}

    def visit(name: str, stack: list[str]) -> None:
        state[name] = 1
        spec = specs[name]
        for target in sorted(spec.references()):
            if target not in specs:
                continue
            if state.get(target) == 1:
                cycle = " -> ".join([*stack[stack.index(target) :], target])
                problems.append(f"{where(spec, target)} cycle of behavior references: {cycle}")
            elif target not in state:
                visit(target, [*stack, target])
        state[name] = 2

    for name in sorted(specs):
        if name not in state:
            visit(name, [name])
    return problems


def _check_reference_outcomes(spec: BehaviorSpec, specs: Mapping[str, BehaviorSpec]) -> list[str]:
    """A behavior used as a state: its transitions must name outcomes it has."""
    problems: list[str] = []

    def walk(state: StateSpec, path: str) -> None:
        outcomes = set(state.params.get("outcomes") or []) if state.block in MACHINES else set()
        breaks = set(state.params.get("break_on") or {}) if state.block == "iterator" else set()
        for name, child in state.states.items():
            child_path = f"{path}/{name}" if path else name
            target = specs.get(str(child.params.get("name"))) if child.block == "behavior" else None
            if target is not None:
                at = f"{spec.path or spec.name}:{child.line}: state {child_path}:"
                own = set(target.outcomes)
                for outcome in child.transitions:
                    if outcome not in own and outcome != PREEMPTED:
                        problems.append(f"{at} behavior {target.name} has no outcome {outcome!r}")
                if state.block in MACHINES:
                    for outcome in sorted(own - set(child.transitions) - outcomes):
                        problems.append(f"{at} outcome {outcome!r} leads nowhere")
                elif state.block == "iterator":
                    taken = {*(state.params.get("continue_on") or []), *breaks}
                    for outcome in sorted(own - taken):
                        problems.append(
                            f"{at} outcome {outcome!r} is neither in continue_on nor in break_on"
                        )
            walk(child, child_path)

    walk(spec.root, "")
    return problems
