"""YAML with line numbers: the one loader of behavior files, personas and scenarios.

Every error in a hand-written file should name its line. :func:`load_located` parses
YAML once (libyaml's parser when PyYAML has it: the daemon parses every behavior file
on its start path) into mappings and lists that remember the line of themselves, of
each key and of each item; a duplicate key is an error, as it is a mistake. Plain
``dict`` and ``list`` code reads them as usual; :func:`lines_by_path` flattens the
lines for a pydantic error's location, :func:`plain` drops them. :func:`load_plain` reads
plain data files (an activity's content) with the same bound on aliases.

YAML aliases (``*name``) reuse a node anchored earlier (``&name``); they are allowed, but a
few hundred bytes of aliases of aliases stand for billions of nodes once walked (an
"alias bomb"), so every load refuses a document whose aliases add more than
:data:`MAX_ALIAS_NODES` nodes, before anything walks it.
"""

from __future__ import annotations

from typing import Any

import yaml

MAX_ALIAS_NODES = 10_000
"""How many nodes a document's aliases may add once written out (hand-written files reuse
a block or two)."""

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


_SafeLoader: type[yaml.SafeLoader] = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


class _Loader(_SafeLoader):  # type: ignore[misc,valid-type]
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


def _children(node: yaml.Node) -> list[yaml.Node]:
    if isinstance(node, yaml.MappingNode):
        return [child for pair in node.value for child in pair]
    if isinstance(node, yaml.SequenceNode):
        return list(node.value)
    return []


def check_aliases(root: yaml.Node) -> None:
    """Refuse a node graph whose aliases add more than :data:`MAX_ALIAS_NODES` nodes.

    The composed graph holds each anchored node once, however often it is aliased: this
    counts each node once (iteratively, memoized), adds a node's written-out size at each
    repeated use, and stops as soon as the sum is over the bound.

    Raises:
        yaml.composer.ComposerError: too many nodes through aliases, or an alias inside
            the node it names; the mark is the node that holds that alias.
    """
    sizes: dict[int, int] = {}  # id -> nodes written out; the graph keeps the nodes alive
    open_: set[int] = set()
    added = 0
    stack: list[tuple[yaml.Node, yaml.Node, bool]] = [(root, root, False)]
    while stack:
        node, parent, done = stack.pop()
        key = id(node)
        if done:
            open_.discard(key)
            sizes[key] = 1 + sum(sizes[id(child)] for child in _children(node))
            continue
        if key in open_:
            raise yaml.composer.ComposerError(
                None, None, "an alias refers to a node that contains it", parent.start_mark
            )
        if key in sizes:  # a repeated use: an alias
            added += sizes[key]
            if added > MAX_ALIAS_NODES:
                raise yaml.composer.ComposerError(
                    None,
                    None,
                    f"aliases written out add more than {MAX_ALIAS_NODES} nodes",
                    parent.start_mark,
                )
            continue
        open_.add(key)
        stack.append((node, parent, True))
        stack.extend((child, node, False) for child in reversed(_children(node)))


def _load(text: str, loader_class: type[yaml.SafeLoader]) -> Any:
    """``yaml.load`` with :func:`check_aliases` between composing and constructing."""
    loader = loader_class(text)
    try:
        node = loader.get_single_node()
        if node is None:
            return None
        # An alias is written ``*name``: a text without an asterisk has none, and its
        # graph is a tree (the walk was a third of loading the behaviors at start).
        if "*" in text:
            check_aliases(node)
        return loader.construct_document(node)
    finally:
        loader.dispose()


def load_located(text: str) -> Any:
    """The document in ``text`` with its lines.

    Raises:
        yaml.YAMLError: not valid YAML, a key given twice, or aliases over the bound
            (``MarkedYAMLError`` carries the place).
    """
    return _load(text, _Loader)  # _Loader is a safe loader


def load_plain(text: str) -> Any:
    """The document in ``text`` as ``yaml.safe_load`` reads it, aliases bounded.

    Raises:
        yaml.YAMLError: not valid YAML, or aliases over the bound.
    """
    return _load(text, _SafeLoader)


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
    """The line of every key and item under ``data``, by its path from the top.

    A mapping or list used again through an alias is walked once, at its first place:
    under a later one a field has no line of its own, and a lookup of the innermost
    place it knows finds the alias's.
    """
    out: dict[Path_, int] = {}
    _collect_lines(data, path, out, set())
    return out


def _collect_lines(data: Any, path: Path_, out: dict[Path_, int], seen: set[int]) -> None:
    if not isinstance(data, Located | LocatedList) or id(data) in seen:
        return
    seen.add(id(data))
    if isinstance(data, Located):
        for key, value in data.items():
            out[(*path, key)] = data.key_lines.get(key, data.line)
            _collect_lines(value, (*path, key), out, seen)
    else:
        for index, value in enumerate(data):
            out[(*path, index)] = data.item_lines[index]
            _collect_lines(value, (*path, index), out, seen)


def plain(value: Any) -> Any:
    """Located mappings and lists as plain ones, recursively (to save or compare)."""
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, list):
        return [plain(v) for v in value]
    return value
