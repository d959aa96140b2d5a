"""Placeholders checked before a behavior runs: each must bind to something.

A placeholder that binds to nothing makes the robot say an empty sentence, in silence.
The loader refuses it as it refuses a missing state, one ``file:line: state PATH:
message`` each, so that ``dms behavior check`` and a reload in the daemon agree
(:func:`placeholder_problems`, called per library: it reads the content files, and
behaviors used as states share userdata). The names a state gives the robot (frames,
gestures...) are checked per file, by :mod:`activities.names`.

A placeholder can be provided by a profile (``user``: a field of the profile model, an
attribute the question bank fills or a ``set_param`` state sets; ``robot`` and ``env``:
the parameters the daemon documents, :mod:`activities.known`; another name needs a
default, as a free user attribute does, for a robot that does not publish it), the
activity's ``args`` (not checked), a content file (``content.FILE...``:
the file and its fields must exist) or a userdata key: declared in ``userdata``, or
written by a state anywhere in the behavior (``set_data``, ``sample``, ``ask``,
``menu``, ``wait_event``, ``decide``, an iterator's ``item_key`` and ``index_key``), or
named by a ``remapping``.
Where a key's value comes from a content file (a sampled question, an iterated joke)
its fields are known, and a misspelled field is found too. A default
(``{user.name|my friend}``) is for a value not set yet (a key only some runs set, a free
profile attribute); it does not excuse a misspelling: ``{user.nmae|there}`` would always
say "there", so a name close to a known one is refused, default or not.

A ``play_media`` whose ``file`` is a letter away from a medium the content files list
is refused the same way (:func:`activities.known.media_problem`).
"""

from __future__ import annotations

import difflib
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any

from activities.blocks import BLOCKS, holds_placeholder
from activities.engine import read_content
from activities.errors import BehaviorError
from activities.known import PARAMETERS, known_media, media_problem
from activities.spec import BehaviorSpec, StateSpec
from activities.template import PLACEHOLDER, PROFILE_NAMESPACES, is_single_placeholder
from memory.parameters import user_parameter_types

OPEN_NAMESPACES = ("args",)
"""Namespaces whose names are not known before the run."""
USER = "user"

# ---------------------------------------------------------------- shapes


@dataclass(frozen=True)
class Anything:
    """A value nothing is known of: any path below it may bind."""


@dataclass(frozen=True)
class Scalar:
    """A number, a string, a truth value: nothing below it."""


@dataclass(frozen=True)
class Fields:
    """A mapping whose keys are known (from a content file, or written in the file)."""

    fields: tuple[tuple[str, Shape], ...]

    def get(self, key: str) -> Shape | None:
        return dict(self.fields).get(key)

    def names(self) -> list[str]:
        return [name for name, _ in self.fields]


@dataclass(frozen=True)
class Items:
    """A list; ``item`` is what any of its items may be (None: nothing known)."""

    item: Shape | None


Shape = Anything | Scalar | Fields | Items
ANYTHING = Anything()
SCALAR = Scalar()
MAX_DEPTH = 8
"""Below this depth in a content file, anything may bind (no deeper shape is kept)."""


def shape_of(value: Any, depth: int = 0) -> Shape:
    """The shape of a value as written: a content file's, or a userdata's start value."""
    if depth > MAX_DEPTH:
        return ANYTHING
    if isinstance(value, dict):
        return Fields(tuple(sorted((str(k), shape_of(v, depth + 1)) for k, v in value.items())))
    if isinstance(value, list):
        item: Shape | None = None
        for entry in value:
            item = union(item, shape_of(entry, depth + 1))
        return Items(item)
    return SCALAR


def union(a: Shape | None, b: Shape | None) -> Shape | None:
    """What a value of either shape may be (lenient: unlike shapes give anything)."""
    if a is None or b is None:
        return a if b is None else b
    if a == b:
        return a
    if isinstance(a, Fields) and isinstance(b, Fields):
        mine, theirs = dict(a.fields), dict(b.fields)
        merged = {k: union(mine.get(k), theirs.get(k)) or ANYTHING for k in {*mine, *theirs}}
        return Fields(tuple(sorted(merged.items())))
    if isinstance(a, Items) and isinstance(b, Items):
        return Items(union(a.item, b.item))
    return ANYTHING


def item_of(shape: Shape) -> Shape:
    """What one item of a list of this shape is (an iterator's item, a sample's draw)."""
    if isinstance(shape, Items) and shape.item is not None:
        return shape.item
    return ANYTHING


@dataclass(frozen=True)
class Missing:
    """Why a path binds to nothing: where it stops, and the names that were there."""

    depth: int
    """How many names of the path were found."""
    names: tuple[str, ...]
    reason: str


def walk(shape: Shape, parts: Sequence[str], depth: int) -> Shape | Missing:
    """The shape at ``parts`` below ``shape``, or where and why it binds to nothing."""
    for index, part in enumerate(parts, start=depth):
        if isinstance(shape, Anything):
            return shape
        if isinstance(shape, Fields):
            found = shape.get(part)
            if found is None:
                return Missing(index, tuple(shape.names()), f"has no field {part!r}")
            shape = found
        elif isinstance(shape, Items):
            if not part.isdigit():
                return Missing(index, (), "is a list: an item is read by its index (.0)")
            shape = item_of(shape)
        else:
            return Missing(index, (), "is a single value, with nothing below it")
    return shape


# ---------------------------------------------------------------- userdata keys

ContentReader = Callable[[str], Any]
"""A content file's data by its name (``quiz``); raises BehaviorError when there is none."""


class ContentShapes:
    """The shapes of the content files, each read once for all the behaviors checked."""

    def __init__(
        self, read: ContentReader, names: Sequence[str], media: Sequence[str] = ()
    ) -> None:
        self.read = read
        self.names = tuple(names)
        self.media = tuple(media)
        """The media files the content files list (what ``play_media`` may name)."""
        self._files: dict[str, Shape | str] = {}

    def shape(self, name: str) -> Shape | str:
        """The file's shape, or why there is none."""
        if name not in self._files:
            try:
                self._files[name] = shape_of(self.read(name))
            except BehaviorError as error:
                missing = f"content file {name}.yaml not found"
                self._files[name] = (
                    f"names no content file {name}.yaml" if str(error) == missing else str(error)
                )
        return self._files[name]


class Bindings:
    """Everything a behavior's placeholders may bind to: its userdata keys, with what is
    known of their values, and the content files."""

    def __init__(self, content: ContentShapes) -> None:
        self.content = content
        self.keys: dict[str, Shape] = {}
        self.user: set[str] = set(user_parameter_types())
        """The names ``{user.NAME}`` may bind: the profile's, and what ``set_param`` sets."""

    def resolve(self, path: str) -> Shape | Missing:
        """The shape ``{path}`` binds to, or why it binds to nothing."""
        parts = path.split(".")
        head = parts[0]
        if head in OPEN_NAMESPACES:
            return ANYTHING
        if head == USER:
            if len(parts) == 1 or parts[1] in self.user:
                return ANYTHING
            return Missing(1, tuple(sorted(self.user)), "has no field " + repr(parts[1]))
        known = PARAMETERS.get(head)
        if known is not None:
            if len(parts) == 1 or parts[1] in known:
                return ANYTHING
            return Missing(1, tuple(known), "has no parameter " + repr(parts[1]))
        if head == "content" and len(parts) >= 2:
            shape = self.content.shape(parts[1])
            if isinstance(shape, str):
                return Missing(1, self.content.names, shape)
            return walk(shape, parts[2:], 2)
        if head not in self.keys:
            names = (*self.keys, *PROFILE_NAMESPACES, "args", "content")
            return Missing(0, tuple(names), "is no userdata key, profile, args or content")
        return walk(self.keys[head], parts[1:], 1)

    def shape(self, value: Any) -> Shape:
        """What a value written in a state is once bound (a single placeholder: what it
        binds to, when known)."""
        if isinstance(value, str) and is_single_placeholder(value):
            match = PLACEHOLDER.fullmatch(value.strip())
            assert match is not None
            found = self.resolve(match.group(1))
            return ANYTHING if isinstance(found, Missing) else found
        if holds_placeholder(value):
            return ANYTHING
        return shape_of(value)


def _states(state: StateSpec) -> Iterator[tuple[str, StateSpec]]:
    """Every state below ``state`` with its path, parents first."""
    for name, child in state.states.items():
        yield name, child
        for path, below in _states(child):
            yield f"{name}/{path}", below


def _written(state: StateSpec, bind: Bindings) -> list[tuple[str, Shape]]:
    """The userdata keys a state writes (or declares), with what their values are."""
    params = state.params
    found: list[tuple[str, Shape]] = []
    for key, value in (params.get("userdata") or {}).items():
        found.append((str(key), bind.shape(value)))
    block = state.block
    if block == "set_data":
        for key, value in (params.get("values") or {}).items():
            found.append((str(key), bind.shape(value)))
        found.extend((str(key), SCALAR) for key in params.get("add") or {})
        for key, value in (params.get("append") or {}).items():
            found.append((str(key), Items(bind.shape(value))))
    elif block in ("ask", "menu", "wait_event"):
        default = {"ask": "answer", "menu": "choice", "wait_event": None}[block]
        key = params.get("key", default)
        if isinstance(key, str):
            found.append((key, SCALAR))
    elif block == "decide":
        found.append(("decision", SCALAR))
    elif block == "sample":
        if params.get("range") is not None:
            drawn: Shape = SCALAR
        else:
            drawn = item_of(bind.shape(params.get("items")))
        if isinstance(params.get("key"), str):
            found.append((params["key"], Items(drawn)))
    elif block == "iterator":
        items = params.get("items")
        item = SCALAR if isinstance(items, int) else item_of(bind.shape(items))
        found.append((str(params.get("item_key", "item")), item))
        if isinstance(params.get("index_key"), str):
            found.append((params["index_key"], SCALAR))
    return found


MAX_PASSES = 6
"""A key's value may come from another key (a sample of a sampled list): passes over
the writers until nothing changes; deeper chains are taken as anything."""


def collect_keys(roots: Sequence[StateSpec], bind: Bindings) -> None:
    """Fill ``bind.keys`` with every key the states under ``roots`` write."""
    states = [*roots, *(state for root in roots for _, state in _states(root))]
    for _ in range(MAX_PASSES):
        keys: dict[str, Shape] = {}
        for state in states:
            for key, shape in _written(state, bind):
                keys[key] = union(keys.get(key), shape) or ANYTHING
        if keys == bind.keys:
            break
        bind.keys = keys
    else:
        bind.keys = dict.fromkeys(bind.keys, ANYTHING)
    for state in states:  # names a remapping gives: whatever they stand for
        for key in (*state.remapping, *state.remapping.values()):
            bind.keys.setdefault(key, ANYTHING)
        name = state.params.get("name")
        if state.block == "set_param" and isinstance(name, str):
            bind.user.add(name)


# ---------------------------------------------------------------- placeholders


def _strings(value: Any) -> Iterator[str]:
    if isinstance(value, str):
        yield value
    elif isinstance(value, list):
        for item in value:
            yield from _strings(item)
    elif isinstance(value, dict):
        for item in value.values():
            yield from _strings(item)


def _close(path: str, missing: Missing) -> str | None:
    """The path with the name where it stops replaced by the closest known one, if any:
    the spelling the designer most likely meant."""
    parts = path.split(".")
    at = parts[missing.depth] if missing.depth < len(parts) else ""
    if not at or not missing.names:
        return None
    close = difflib.get_close_matches(at, list(missing.names), n=1, cutoff=0.6)
    if not close:
        return None
    return ".".join([*parts[: missing.depth], close[0], *parts[missing.depth + 1 :]])


def _message(path: str, missing: Missing, meant: str | None) -> str:
    parts = path.split(".")
    found = ".".join(parts[: missing.depth])
    at = parts[missing.depth] if missing.depth < len(parts) else ""
    subject = found if found else at
    hint = f"; did you mean {{{meant}}}?" if meant else ""
    if not meant and parts[0] == USER and missing.depth == 1:
        hint = f" (a free attribute: give a default, {{{path}|...}}, for users without it)"
    if not meant and parts[0] in PARAMETERS and missing.depth == 1:
        names = ", ".join(missing.names)
        hint = (
            f" (one of {names}; another the robot publishes needs a default, "
            f"{{{path}|...}}, for a robot without it)"
        )
    return f"{{{path}}} binds to nothing: {subject} {missing.reason}{hint}"


def state_placeholder_problems(state: StateSpec, bind: Bindings) -> list[tuple[str, str]]:
    """``(parameter, message)`` for each placeholder of a state that binds to nothing.

    One with a default is refused only when a known name is close to the one written:
    a default stands in for a value not set yet (a key only some runs set, a free
    profile attribute), not for a typo, which would always give the default."""
    if state.block in BLOCKS:
        bound = state.params
    elif state.block == "iterator":
        bound = {"items": state.params.get("items")}
    else:
        return []  # other containers bind no placeholder
    found: list[tuple[str, str]] = []
    for param, value in bound.items():
        for text in _strings(value):
            for match in PLACEHOLDER.finditer(text):
                path, default = match.group(1), match.group(2)
                result = bind.resolve(path)
                if not isinstance(result, Missing):
                    continue
                meant = _close(path, result)
                if default is None or meant is not None:
                    message = _message(path, result, meant)
                    found.append((param, f"{state.block}: parameter {param!r}: {message}"))
    return found


def placeholder_problems(specs: Mapping[str, BehaviorSpec], content: ContentShapes) -> list[str]:
    """Placeholders of ``specs`` that bind to nothing, one ``file:line: state PATH:``
    line each.

    Behaviors that use one another as states share their userdata, so each is checked
    against the keys of all those it is linked with.
    """
    groups = _linked(specs)
    problems: list[str] = []
    for name in sorted(specs):
        spec = specs[name]
        bind = Bindings(content)
        collect_keys([specs[other].root for other in sorted(groups[name])], bind)
        where = str(spec.path or spec.name)
        for path, state in _states(spec.root):
            found = state_placeholder_problems(state, bind)
            found.extend(state_media_problems(state, content.media))
            for param, message in found:
                line = state.param_lines.get(param, state.line)
                problems.append(f"{where}:{line}: state {path}: {message}")
    return problems


def state_media_problems(state: StateSpec, media: Sequence[str]) -> list[tuple[str, str]]:
    """``(parameter, message)`` for a ``play_media`` whose written ``file`` is a
    misspelling of a listed medium (a placeholder is known once bound)."""
    file = state.params.get("file") if state.block == "play_media" else None
    if not isinstance(file, str) or holds_placeholder(file):
        return []
    problem = media_problem(file, media)
    return [] if problem is None else [("file", f"play_media: parameter 'file': {problem}")]


def _linked(specs: Mapping[str, BehaviorSpec]) -> dict[str, set[str]]:
    """For each behavior, the behaviors it is linked with by ``behavior`` states."""
    group = {name: {name} for name in specs}
    for name, spec in specs.items():
        for target in spec.references():
            if target in specs and group[target] is not group[name]:
                merged = group[name] | group[target]
                for member in merged:
                    group[member] = merged
    return group


def content_shapes(dirs: Sequence[Path]) -> ContentShapes:
    """The content files of ``dirs`` as they are now (not the run's cache: a reload
    checks the files it will use)."""
    names = sorted({p.stem for d in dirs if d.is_dir() for p in d.glob("*.yaml")})
    return ContentShapes(partial(read_content, tuple(dirs)), names, known_media(dirs))
