"""Parameters bound at run time: ``"Hello {user.name}"``, ``"{score}"``, ``"{args.text|...}"``.

A placeholder is ``{path}`` or ``{path|default}``; a path is dotted names. Its first
name picks the namespace: ``user``, ``robot``, ``env`` (the profiles), ``args`` (what
the controller passed to the activity), ``content`` (a local content file:
``{content.quiz.questions}`` is ``questions`` in ``content/quiz.yaml``); any other
name is a userdata key (``{question.text}``). A string that is exactly one placeholder
gives the value itself (a list stays a list); inside text, lists read as "a, b and c".
Nothing is evaluated: paths are looked up, never run.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping
from typing import Any

PLACEHOLDER = re.compile(r"\{([A-Za-z_][\w.]*)(?:\|([^{}]*))?\}")
PROFILE_NAMESPACES = ("user", "robot", "env")


class Missing(LookupError):
    """A placeholder named something that has no value and no default."""


Resolver = Callable[[str], Any]
"""Looks up one dotted path; raises :class:`Missing` when there is nothing."""


def has_placeholder(value: object) -> bool:
    return isinstance(value, str) and PLACEHOLDER.search(value) is not None


def is_single_placeholder(value: object) -> bool:
    return isinstance(value, str) and PLACEHOLDER.fullmatch(value.strip()) is not None


def lookup(root: Any, parts: list[str]) -> Any:
    """Walk ``parts`` into mappings (and lists by index); raise Missing if absent."""
    value = root
    for part in parts:
        if isinstance(value, Mapping):
            try:  # one read, not ``in`` then a read: a userdata view reads its parents'
                value = value[part]
            except KeyError:
                raise Missing(part) from None
        elif isinstance(value, list | tuple) and part.isdigit() and int(part) < len(value):
            value = value[int(part)]
        else:
            raise Missing(part)
    return value


def as_text(value: Any) -> str:
    """How a value reads inside a sentence."""
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float) and value.is_integer():
        return str(int(value))
    if isinstance(value, list | tuple):
        items = [as_text(item) for item in value]
        if len(items) <= 1:
            return "".join(items)
        return ", ".join(items[:-1]) + " and " + items[-1]
    return str(value)


def render(value: Any, resolve: Resolver) -> Any:
    """Bind every placeholder in ``value`` (strings, lists and mappings, recursively)."""
    if isinstance(value, str):
        whole = PLACEHOLDER.fullmatch(value.strip())
        if whole is not None:
            return _one(whole, resolve)
        return PLACEHOLDER.sub(lambda m: as_text(_one(m, resolve)), value)
    if isinstance(value, list):
        return [render(item, resolve) for item in value]
    if isinstance(value, dict):
        return {key: render(item, resolve) for key, item in value.items()}
    return value


def _one(match: re.Match[str], resolve: Resolver) -> Any:
    path, default = match.group(1), match.group(2)
    try:
        return resolve(path)
    except Missing:
        if default is not None:
            return default
        return ""
