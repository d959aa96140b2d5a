"""YAML with line numbers: the one loader of behavior files, personas and scenarios.

Every error in a hand-written file should name its line. :func:`load_located` parses
YAML once (libyaml's parser when PyYAML has it: the daemon parses every behavior file
on its start path) into mappings and lists that remember the line of themselves, of
each key and of each item; a duplicate key is an error, as it is a mistake. Plain
``dict`` and ``list`` code reads them as usual; :func:`lines_by_path` flattens the
lines for a pydantic error's location, :func:`plain` drops them.
"""

from __future__ import annotations

from typing import Any

import yaml

Path_ = tuple[str | int, ...]
"""A field's place in the document: keys and item indexes from the top."""


class Located(dict[str, Any]):
    """A mapping read from YAML that remembers the line of itself and of each key."""

    line: int = 0
    key_lines: dict[str, int]


class LocatedList(list[Any]):
    """A sequence read from YAML that remembers the line of itself and of each item."""

    line: int = 0
    item_lines: list[int]


class _Loader(getattr(yaml, "CSafeLoader", yaml.SafeLoader)):  # type: ignore[misc]
    """Safe loading, with :class:`Located` mappings and :class:`LocatedList` sequences."""


def _construct_mapping(loader: _Loader, node: yaml.MappingNode) -> Located:
    loader.flatten_mapping(node)
    out = Located()
    out.line = node.start_mark.line + 1
    out.key_lines = {}
    for key_node, value_node in node.value:
        key = loader.construct_object(key_node, deep=True)
        if not isinstance(key, str):
            key = str(key).lower() if isinstance(key, bool) else str(key)
        if key in out:
            raise yaml.constructor.ConstructorError(
                None, None, f"duplicate key {key!r}", key_node.start_mark
            )
        out[key] = loader.construct_object(value_node, deep=True)
        out.key_lines[key] = key_node.start_mark.line + 1
    return out


def _construct_sequence(loader: _Loader, node: yaml.SequenceNode) -> LocatedList:
    out = LocatedList(loader.construct_object(item, deep=True) for item in node.value)
    out.line = node.start_mark.line + 1
    out.item_lines = [item.start_mark.line + 1 for item in node.value]
    return out


_Loader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_mapping)
_Loader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_SEQUENCE_TAG, _construct_sequence)


def load_located(text: str) -> Any:
    """The document in ``text`` with its lines.

    Raises:
        yaml.YAMLError: not valid YAML, or a key given twice (``MarkedYAMLError``
            carries the place).
    """
    return yaml.load(text, Loader=_Loader)  # _Loader is a safe loader


def yaml_error(error: yaml.YAMLError, where: str) -> str:
    """``WHERE:LINE:COLUMN: not valid YAML: problem`` for an error of :func:`load_located`."""
    if isinstance(error, yaml.MarkedYAMLError):
        mark = error.problem_mark or error.context_mark
        at = f":{mark.line + 1}:{mark.column + 1}" if mark is not None else ""
        return f"{where}{at}: not valid YAML: {error.problem or error}"
    return f"{where}: not valid YAML: {error}"


def line_of_key(mapping: Any, key: str | None = None) -> int:
    """The line of ``key`` in a located mapping (or of the mapping); 0 if unknown."""
    if isinstance(mapping, Located):
        if key is not None and key in mapping.key_lines:
            return mapping.key_lines[key]
        return mapping.line
    return 0


def lines_by_path(data: Any, path: Path_ = ()) -> dict[Path_, int]:
    """The line of every key and item under ``data``, by its path from the top."""
    out: dict[Path_, int] = {}
    if isinstance(data, Located):
        for key, value in data.items():
            out[(*path, key)] = data.key_lines.get(key, data.line)
            out.update(lines_by_path(value, (*path, key)))
    elif isinstance(data, LocatedList):
        for index, value in enumerate(data):
            out[(*path, index)] = data.item_lines[index]
            out.update(lines_by_path(value, (*path, index)))
    return out


def plain(value: Any) -> Any:
    """Located mappings and lists as plain ones, recursively (to save or compare)."""
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, list):
        return [plain(v) for v in value]
    return value
