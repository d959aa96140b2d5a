"""Saving an edited behavior into its YAML text without losing what the person wrote.

The file is read with ruamel.yaml's round-trip loader, the edited document (plain JSON
from the page) is merged into it value by value, and it is written back: comments, key
order, quoting and flow or block style stay where nothing changed, so a file opened and
saved unchanged is byte-identical. New states are written in the shipped files' style:
a block's parameters and the transitions on one line each.
"""

from __future__ import annotations

import io
from collections.abc import Mapping
from typing import Any, cast

import yaml as pyyaml
from ruamel.yaml import YAML
from ruamel.yaml.comments import CommentedMap, CommentedSeq
from ruamel.yaml.scalarstring import DoubleQuotedScalarString, ScalarString

WIDTH = 4096
"""Never fold a long line: the shipped files keep each sentence on one line."""


def _yaml() -> YAML:
    yaml = YAML(typ="rt")
    yaml.preserve_quotes = True
    yaml.width = WIDTH
    yaml.indent(mapping=2, sequence=4, offset=2)
    return yaml


def load(text: str) -> Any:
    """The round-trip tree of a behavior file's text."""
    return _yaml().load(text)


def dump(tree: Any) -> str:
    out = io.StringIO()
    _yaml().dump(tree, out)
    return out.getvalue()


def to_plain(value: Any) -> Any:
    """A round-trip tree as plain JSON values (what the page edits)."""
    if isinstance(value, Mapping):
        return {str(key): to_plain(item) for key, item in value.items()}
    if isinstance(value, list):
        return [to_plain(item) for item in value]
    if isinstance(value, bool) or value is None:
        return value
    if isinstance(value, int):
        return int(value)
    if isinstance(value, float):
        return float(value)
    return str(value)


def merge(old: Any, new: Any) -> Any:
    """``new`` written over ``old``, keeping ``old``'s nodes (and so their comments and
    style) wherever a value is the same kind."""
    if isinstance(old, CommentedMap) and isinstance(new, Mapping):
        for key in [key for key in old if key not in new]:
            del old[key]
        for key, value in new.items():
            old[key if key in old else _string(key)] = (
                merge(old[key], value) if key in old else fresh(value, key)
            )
        if list(old) != list(new):
            for key in new:
                old.move_to_end(key)
        return old
    if isinstance(old, CommentedSeq) and isinstance(new, list):
        if len(old) == len(new):
            for index, value in enumerate(new):
                old[index] = merge(old[index], value)
            return old
        seq = CommentedSeq(fresh(item) for item in new)
        if old.fa.flow_style():
            seq.fa.set_flow_style()
        return seq
    if _same(old, new):
        return old
    if isinstance(old, ScalarString) and isinstance(new, str):
        return type(old)(new)  # the same quoting
    return fresh(new)


def _same(old: Any, new: Any) -> bool:
    if isinstance(old, bool) or isinstance(new, bool):
        return isinstance(old, bool) and isinstance(new, bool) and old == new
    if isinstance(old, str) != isinstance(new, str):
        return False
    return bool(old == new)


def _flat(value: Any) -> bool:
    """Short enough for one line: scalars, and lists or mappings of scalars."""
    items = value.values() if isinstance(value, Mapping) else value
    if isinstance(value, Mapping | list):
        return all(
            not isinstance(item, Mapping | list) or (isinstance(item, list) and _flat(item))
            for item in items
        )
    return True


def _string(text: str) -> str:
    """A new string, double-quoted where it holds a space or a brace (as the shipped files
    write sentences) or where the loader (YAML 1.1) would read it as something else:
    ``yes`` is a boolean there."""
    if " " in text or "{" in text:
        return cast(str, DoubleQuotedScalarString(text))
    try:
        same = bool(pyyaml.safe_load(text) == text)
    except pyyaml.YAMLError:
        same = False
    return text if same else cast(str, DoubleQuotedScalarString(text))


def fresh(value: Any, key: object = None) -> Any:
    """A new value as the shipped files write it: mappings of scalars and lists on one
    line (``{text: ...}``), states and containers as blocks."""
    if isinstance(value, Mapping):
        tree = CommentedMap((_string(str(k)), fresh(v, k)) for k, v in value.items())
        if key not in ("states", "state", "userdata") and _flat(value) and value:
            tree.fa.set_flow_style()
        return tree
    if isinstance(value, list):
        seq = CommentedSeq(fresh(item) for item in value)
        if _flat(value):
            seq.fa.set_flow_style()
        return seq
    if isinstance(value, str):
        return _string(value)
    return value


def new_text(doc: Mapping[str, Any]) -> str:
    """A new behavior file's text."""
    return dump(fresh(doc))


def edited_text(original: str, doc: Mapping[str, Any]) -> str:
    """``original`` with ``doc`` merged into it; ``original`` itself when nothing changed."""
    tree = load(original)
    if not isinstance(tree, CommentedMap):
        return new_text(doc)
    if to_plain(tree) == doc:
        return original
    return dump(merge(tree, doc))
