"""Checking the document being edited with the real loader, message by message.

The page sends the whole behavior as JSON after each change; :func:`check_document`
writes it as YAML, parses it with :func:`activities.spec.parse_text` (the loader the
daemon uses) and its references with :func:`activities.spec.check_references`, and
returns each problem with the state path and the parameter it concerns, so that the
page shows it at the field: the placeholders that bind to nothing
(:func:`activities.checks.placeholder_problems`) are the loader's too. It adds its own
warning for a ``{`` that starts no placeholder (the robot says it as written).
"""

from __future__ import annotations

import re
from collections.abc import Iterator, Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Literal

import yaml

from activities.blocks import BLOCKS
from activities.checks import ContentShapes, placeholder_problems
from activities.errors import BehaviorError
from activities.spec import (
    CONTAINERS,
    GROUPS,
    STATE_KEYS,
    TOP_KEYS,
    BehaviorSpec,
    StateSpec,
    check_references,
    parse_text,
)
from activities.template import PLACEHOLDER

WHERE = "<studio>"
"""The file name given to the loader: problems start with it, then the line."""

_PROBLEM = re.compile(
    r"^(?P<where>[^:]*)(?::(?P<line>\d+))?:(?: state (?P<path>[^:]*):)? (?P<msg>.*)$"
)
_PARAM = re.compile(r"parameter '([^']+)'")
_TRANSITION_WORDS = ("transition ", "leads nowhere", "has no outcome")


@dataclass(frozen=True)
class Message:
    """One problem, where the page shows it."""

    path: str
    """The state's path (``GAME/CALLS``); empty: the behavior itself."""
    param: str | None
    """The parameter it concerns (``transitions`` for a transition), if any."""
    text: str
    severity: Literal["error", "warning"] = "error"


@dataclass
class Report:
    """What the page needs after a change: the messages and each state's outcomes."""

    ok: bool
    messages: list[Message] = field(default_factory=list)
    outcomes: dict[str, list[str]] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        return {
            "ok": self.ok,
            "messages": [asdict(message) for message in self.messages],
            "outcomes": self.outcomes,
        }


def document_text(doc: Mapping[str, Any]) -> str:
    """The document as plain YAML, for the loader (its lines are never shown)."""
    return yaml.safe_dump(dict(doc), sort_keys=False, allow_unicode=True, width=4096)


def parse_message(problem: str) -> Message:
    """A loader's ``FILE:LINE: state PATH: message`` as a :class:`Message`."""
    found = _PROBLEM.match(problem)
    if found is None:
        return Message("", None, problem)
    text = found.group("msg")
    param_match = _PARAM.search(text)
    param = param_match.group(1) if param_match else None
    if param is None and text.startswith("activity:"):
        param = "activity"  # the Activity form's
    elif param is None and any(word in text for word in _TRANSITION_WORDS):
        param = "transitions"
    head = text.split(":", 1)[0]
    if param is None and not found.group("path") and head in TOP_KEYS:
        param = head  # a key at the behavior's top: shown at its field

    return Message(found.group("path") or "", param, text)


def check_document(
    doc: Mapping[str, Any],
    others: Mapping[str, BehaviorSpec] | None = None,
    content: ContentShapes | None = None,
) -> Report:
    """Check ``doc`` as the loader would load it beside ``others`` (the behaviors it may
    use as states), its placeholders against ``content`` (the content files)."""
    messages: list[Message] = []
    spec: BehaviorSpec | None = None
    try:
        spec = parse_text(document_text(doc), WHERE)
    except BehaviorError as error:
        messages.extend(parse_message(problem) for problem in error.problems)
    if spec is not None and others is not None:
        specs = {**others, spec.name: spec}
        prefix = f"{spec.name}:"
        messages.extend(
            parse_message(problem)
            for problem in check_references(specs)
            if problem.startswith(prefix)
        )
        if content is not None:
            messages.extend(
                parse_message(problem)
                for problem in placeholder_problems(specs, content)
                if problem.startswith(prefix)
            )
    ok = not messages
    messages.extend(placeholder_warnings(doc))
    return Report(ok, messages, state_outcomes(doc, others or {}))


# ---------------------------------------------------------------- the states as written


def block_of(state: Mapping[str, Any]) -> str | None:
    """The block (or container) key of a state as written, if it has exactly one."""
    kinds = [key for key in state if key not in STATE_KEYS]
    if len(kinds) == 1 and (kinds[0] in BLOCKS or kinds[0] in CONTAINERS):
        return kinds[0]
    return None


def children_of(state: Mapping[str, Any]) -> dict[str, Any]:
    """The states inside a container state as written (empty for a block)."""
    block = block_of(state)
    params = state.get(block) if block else None
    if not isinstance(params, dict):
        return {}
    inner = params.get("states" if block in GROUPS else "state")
    return inner if isinstance(inner, dict) else {}


def walk(states: Mapping[str, Any], path: str = "") -> Iterator[tuple[str, dict[str, Any]]]:
    """Every state as written, with its path, parents first."""
    for name, state in states.items():
        if not isinstance(state, dict):
            continue
        here = f"{path}/{name}" if path else str(name)
        yield here, state
        yield from walk(children_of(state), here)


def _as_spec(name: str, state: Mapping[str, Any]) -> StateSpec | None:
    block = block_of(state)
    if block is None:
        return None
    params = state.get(block)
    params = dict(params) if isinstance(params, dict) else {}
    children = {
        child: spec
        for child, raw in children_of(state).items()
        if isinstance(raw, dict) and (spec := _as_spec(str(child), raw)) is not None
    }
    params.pop("states" if block in GROUPS else "state", None)
    return StateSpec(str(name), block, params, states=children)


def state_outcomes(
    doc: Mapping[str, Any], library: Mapping[str, BehaviorSpec]
) -> dict[str, list[str]]:
    """Each state's outcomes, by path, as the loader works them out (also for a
    document that does not load: the page draws their ports)."""
    out: dict[str, list[str]] = {}
    states = doc.get("states")
    for path, state in walk(states if isinstance(states, dict) else {}):
        spec = _as_spec(path.rsplit("/", 1)[-1], state)
        if spec is None:
            continue
        try:
            out[path] = [str(outcome) for outcome in spec.outcomes(library)]
        except (TypeError, ValueError, AttributeError):
            out[path] = list(BLOCKS[spec.block].OUTCOMES) if spec.block in BLOCKS else []
    return out


# ---------------------------------------------------------------- placeholders


def _mapping(value: Any) -> dict[str, Any]:
    return value if isinstance(value, dict) else {}


def _strings(value: Any, param: str) -> Iterator[tuple[str, str]]:
    if isinstance(value, str):
        yield param, value
    elif isinstance(value, list):
        for item in value:
            yield from _strings(item, param)
    elif isinstance(value, dict):
        for item in value.values():
            yield from _strings(item, param)


def placeholder_warnings(doc: Mapping[str, Any]) -> list[Message]:
    """A ``{`` that starts no placeholder: the robot would say it as written."""
    found: list[Message] = []
    states = doc.get("states")
    for path, state in walk(states if isinstance(states, dict) else {}):
        block = block_of(state)
        if block is None:
            continue
        params = {
            key: value
            for key, value in _mapping(state.get(block)).items()
            if key not in ("states", "state")
        }
        for param, text in (pair for key, value in params.items() for pair in _strings(value, key)):
            found.extend(Message(path, param, note, "warning") for note in _text_notes(text))
    return found


def _text_notes(text: str) -> list[str]:
    starts = {match.start() for match in PLACEHOLDER.finditer(text)}
    notes: list[str] = []
    for index, char in enumerate(text):
        if char == "{" and index not in starts:
            end = text.find("}", index)
            shown = text[index : end + 1] if end != -1 else text[index : index + 20]
            notes.append(
                f"{shown!r} is not a placeholder: write {{name}} or {{name|default}} "
                "(dotted names, no spaces)"
            )
    return notes


_PARSED: dict[Path, tuple[tuple[int, int], BehaviorSpec | None]] = {}
"""Each file's parse, kept while its size and modification time stay the same: the page
checks after every change, and the folder rarely changes meanwhile."""


def folder_specs(*directories: Path) -> dict[str, BehaviorSpec]:
    """The behaviors of ``directories`` that load (later folders win), for references."""
    specs: dict[str, BehaviorSpec] = {}
    for directory in directories:
        for path in sorted(directory.glob("*.yaml")):
            spec = _parsed(path)
            if spec is not None:
                specs[spec.name] = spec
    return specs


def _parsed(path: Path) -> BehaviorSpec | None:
    try:
        stat = path.stat()
    except OSError:
        return None
    stamp = (stat.st_mtime_ns, stat.st_size)
    kept = _PARSED.get(path)
    if kept is not None and kept[0] == stamp:
        return kept[1]
    try:
        spec: BehaviorSpec | None = parse_text(path.read_text(encoding="utf-8"), str(path), path)
    except (BehaviorError, OSError, UnicodeDecodeError):
        spec = None
    _PARSED[path] = (stamp, spec)
    return spec
