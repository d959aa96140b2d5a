"""The behavior library: loads a directory of behavior files and builds activities.

``BehaviorLibrary.load()`` reads the sixteen shipped behaviors (``activities/behaviors``);
every file is checked (blocks, parameters, transitions, reachability, references and
their cycles, the frames and gestures it names, the placeholders it binds) and a bad
file is refused with ``file:line: state PATH: message``. ``reload()`` swaps in a new
version only when every file is good, so a running daemon keeps the previous behaviors
otherwise.
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Mapping, Sequence
from pathlib import Path
from typing import Any, Protocol

from activities.activity import Activity
from activities.blocks import BLOCKS
from activities.checks import content_shapes, placeholder_problems
from activities.containers import (
    Concurrence,
    ConcurrenceWait,
    Guard,
    Iterator,
    StateMachine,
    Trigger,
)
from activities.context import ActivityContext
from activities.declaration import count_problem, install_catalogue
from activities.engine import Io, Node, Runtime, clear_content_cache
from activities.errors import BehaviorError, UnknownBehavior
from activities.gaze import GazeKeeper
from activities.spec import BehaviorSpec, StateSpec, check_references, parse_file
from activities.task_frames import TaskFrame, TaskFrames
from dms.kernel.activity_names import Catalogue

PACKAGE_DIR = Path(__file__).parent
BEHAVIORS_DIR = PACKAGE_DIR / "behaviors"
CONTENT_DIR = PACKAGE_DIR / "content"


def content_dirs(directory: Path | None) -> tuple[Path, ...]:
    """Where the behaviors of ``directory`` find their content files, first first: its
    own ``content``, its parent's, the shipped one."""
    dirs = []
    if directory is not None:
        dirs.append(directory / "content")
        dirs.append(directory.parent / "content")
    dirs.append(CONTENT_DIR)
    return tuple(dict.fromkeys(dirs))


def _placeholder_problems(specs: Mapping[str, BehaviorSpec], directory: Path) -> list[str]:
    return placeholder_problems(specs, content_shapes(content_dirs(directory)))


def load_specs(directory: Path) -> tuple[dict[str, BehaviorSpec], list[str]]:
    """Every ``*.yaml`` in ``directory`` parsed and checked: (specs, problems)."""
    specs: dict[str, BehaviorSpec] = {}
    problems: list[str] = []
    if not directory.is_dir():
        return specs, [f"{directory}: not a directory"]
    for path in sorted(directory.glob("*.yaml")):
        try:
            spec = parse_file(path)
        except BehaviorError as error:
            problems.extend(error.problems)
            continue
        if spec.name != path.stem:
            problems.append(f"{path}:1: name {spec.name!r} differs from the file name")
        if spec.name in specs:
            problems.append(f"{path}:1: behavior {spec.name!r} defined twice")
        specs[spec.name] = spec
    problems.extend(check_references(specs))
    problems.extend(_placeholder_problems(specs, directory))
    declared = sum(spec.activity is not None for spec in specs.values())
    if (too_many := count_problem(declared)) is not None:
        problems.append(f"{directory}: {too_many}")
    return specs, problems


OutcomeCheck = Callable[[str, Collection[str]], Sequence[object]]
"""``check(component, outcomes)``: the problems of a DMSL component used by a decide state
(``functools.partial(dms.rules.check_outcomes, ruleset)``); each problem printed as is."""


def decision_problems(specs: Mapping[str, BehaviorSpec], check: OutcomeCheck) -> list[str]:
    """Decide states whose DMSL component may activate something not among their outcomes.

    Each problem is ``FILE:LINE: state PATH: RULES-FILE:LINE:COL: message``, naming both
    the behavior's state and the rule's activation.
    """
    problems: list[str] = []

    def walk(spec: BehaviorSpec, state: StateSpec, path: str) -> None:
        for name, child in state.states.items():
            child_path = f"{path}/{name}" if path else name
            if child.block == "decide":
                component = str(child.params.get("component"))
                at = f"{spec.path or spec.name}:{child.line}: state {child_path}:"
                outcomes = BLOCKS["decide"].outcomes_for(child.params)
                problems.extend(f"{at} {problem}" for problem in check(component, outcomes))
            walk(spec, child, child_path)

    for name in sorted(specs):
        walk(specs[name], specs[name].root, "")
    return problems


class LiveRuleFiles(Protocol):
    """The daemon's reloadable rules (``dms.rules.LiveRules``), as the behaviors see them."""

    def reload(self) -> Sequence[object]: ...

    def check_outcomes(self, component: str, outcomes: Collection[str]) -> Sequence[object]: ...


def decision_warnings(library: BehaviorLibrary, rules: LiveRuleFiles | None) -> list[str]:
    """Decide states whose DMSL component may activate something they do not declare.

    A warning, not a refusal: such an activation is ignored and the state's ``default``
    decides, so the robot still works.
    """
    if rules is None:
        return []
    return library.check_decisions(rules.check_outcomes)


def reload_rules_and_behaviors(
    library: BehaviorLibrary, rules: LiveRuleFiles | None
) -> list[tuple[str, str]]:
    """Reload the rules files and the behaviors folder (SIGHUP, ``reload_rules``).

    Each keeps its previous version when the new one does not verify. Returns
    ``(key, line)`` pairs for ``dms/errors``: every rules problem, one line for refused
    behaviors, then the decide states that the rules and behaviors in force disagree on.
    """
    found: list[tuple[str, str]] = []
    if rules is not None:
        found.extend(("rules", str(problem)) for problem in rules.reload())
    problems = library.reload()
    if not problems:
        library.install_catalogue()
    if problems:
        more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
        found.append(("behaviors", f"{problems[0]}{more}; keeping the previous behaviors"))
    found.extend(("behaviors", line) for line in decision_warnings(library, rules))
    return found


class BehaviorLibrary:
    """The behaviors of one directory, ready to be created as activities."""

    def __init__(self, specs: Mapping[str, BehaviorSpec], directory: Path | None = None):
        self.directory = directory
        self._specs = dict(specs)

    @classmethod
    def load(cls, directory: Path | None = None) -> BehaviorLibrary:
        """Load and check ``directory`` (default: the shipped behaviors)."""
        directory = directory or BEHAVIORS_DIR
        specs, problems = load_specs(directory)
        if problems:
            more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
            raise BehaviorError(problems[0] + more, problems)
        return cls(specs, directory)

    @classmethod
    def for_file(cls, path: Path) -> tuple[BehaviorLibrary, BehaviorSpec]:
        """One file with the behaviors it may reference (its folder's, then the shipped)."""
        spec = parse_file(path)
        specs: dict[str, BehaviorSpec] = {}
        for directory in (BEHAVIORS_DIR, path.parent):
            for other in sorted(directory.glob("*.yaml")):
                if other.resolve() == path.resolve():
                    continue
                try:
                    found = parse_file(other)
                except BehaviorError:
                    continue
                specs[found.name] = found
        specs[spec.name] = spec
        every = [*check_references(specs), *_placeholder_problems(specs, path.parent)]
        problems = [p for p in every if p.startswith(f"{path}:")]
        if problems:
            raise BehaviorError(problems[0], problems)
        return cls(specs, path.parent), spec

    @property
    def names(self) -> frozenset[str]:
        return frozenset(self._specs)

    def declarations(self) -> dict[str, dict[str, Any]]:
        """The behaviors declared activities: name, its ``activity:`` as written."""
        return {n: s.activity for n, s in self._specs.items() if s.activity is not None}

    def install_catalogue(self) -> Catalogue:
        """Put in force the shipped activities plus the ones this library declares (the
        daemon and the simulator at start, and after each reload that took)."""
        return install_catalogue(self.declarations())

    def spec(self, name: str) -> BehaviorSpec:
        try:
            return self._specs[name]
        except KeyError:
            raise UnknownBehavior(f"no behavior named {name!r}") from None

    def check_decisions(self, check: OutcomeCheck) -> list[str]:
        """:func:`decision_problems` of every behavior in the library."""
        return decision_problems(self._specs, check)

    def reload(self) -> list[str]:
        """Re-read the directory; swap in only when every file is good. Problems, or []."""
        specs, problems = load_specs(self.directory or BEHAVIORS_DIR)
        if problems:
            return problems
        self._specs = specs
        clear_content_cache()  # content files may have changed with the behaviors
        return []

    def content_dirs(self) -> tuple[Path, ...]:
        return content_dirs(self.directory)

    def create(
        self, name: str, ctx: ActivityContext, args: Mapping[str, Any] | None = None
    ) -> Activity:
        """A new, not yet started activity of behavior ``name``."""
        spec = self.spec(name)
        runtime = Runtime(ctx, args or {}, self.content_dirs())
        runtime.task_frames = TaskFrames(self._task_frames(spec))
        root = self.build_root(spec, runtime)
        attend = spec.attention()
        gaze = None if attend is None else GazeKeeper(ctx, attend.frame, attend.settings())
        return Activity(name, root, runtime, gaze)

    def _task_frames(self, spec: BehaviorSpec) -> dict[str, TaskFrame]:
        """The task frames of ``spec`` and of the behaviors it runs as states (its own
        win): they share one runtime."""
        frames: dict[str, TaskFrame] = {}
        seen, todo = {spec.name}, list(spec.references())
        while todo:
            name = todo.pop()
            if name in seen or name not in self._specs:
                continue
            seen.add(name)
            frames.update(self._specs[name].frames)
            todo.extend(self._specs[name].references())
        return {**frames, **spec.frames}

    def build_root(self, spec: BehaviorSpec, runtime: Runtime) -> Node:
        return self._build(spec.root, spec.name, runtime)

    def _build(self, state: StateSpec, name: str, rt: Runtime) -> Node:
        io = Io(tuple(state.input_keys), tuple(state.output_keys), dict(state.remapping))
        params = state.params
        if state.block in BLOCKS:
            return BLOCKS[state.block](name, rt, params, io)
        children = {n: self._build(s, n, rt) for n, s in state.states.items()}
        if state.block in ("state_machine", "sequence"):
            machine = StateMachine(
                name,
                params.get("outcomes") or [],
                rt,
                children,
                {n: s.transitions for n, s in state.states.items()},
                params.get("initial") or next(iter(children)),
                io,
                params.get("userdata"),
            )
            machine.kind = state.block
            return machine
        if state.block == "concurrence":
            return Concurrence(
                name,
                params.get("outcomes") or [],
                rt,
                children,
                params.get("outcome_map") or {},
                params["default_outcome"],
                io,
                params.get("userdata"),
                ConcurrenceWait(params.get("wait") or "match"),
            )
        if state.block == "iterator":
            (child,) = children.values()
            return Iterator(
                name,
                state.outcomes(),
                rt,
                child,
                params["items"],
                params.get("item_key", "item"),
                params.get("index_key"),
                params.get("continue_on") or [],
                params.get("break_on") or {},
                params.get("exhausted", "done"),
                io,
            )
        if state.block == "guard":
            (child,) = children.values()
            trigger = Trigger(
                touch=frozenset(params.get("touch") or []),
                keywords=tuple(k.lower() for k in params.get("keywords") or []),
                screen=frozenset(s.lower() for s in params.get("screen") or []),
                timer_s=params.get("timer_s"),
            )
            return Guard(
                name,
                state.outcomes(),
                rt,
                child,
                trigger,
                params.get("outcome", "triggered"),
                io,
            )
        if state.block == "behavior":
            target = self.spec(str(params["name"]))
            node = self._build(target.root, name, rt)
            node.io = io
            node.kind = "behavior"
            return node
        raise BehaviorError(f"unknown block {state.block!r}")
