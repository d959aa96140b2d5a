"""Identifiers that cross the bus and the stores: user ids, item ids, command ids, names.

One rule for all of them, checked where they come in (the bus, the command line, the
stores), so that an id the store would refuse never reaches the decision loop: an
identifier is trimmed of surrounding white space, is not empty, holds no control or
format characters (no NUL, no newline, no bidirectional override: nothing that forges a
log line or that PostgreSQL refuses), none of the characters Zenoh reserves in keys
(an id is a key segment: ``users/<id>``) and has at most :data:`MAX_ID_LENGTH` characters.

Part of the kernel: it imports nothing of the project.
"""

from __future__ import annotations

import re
import unicodedata
from typing import Annotated

from pydantic import AfterValidator, StringConstraints

MAX_ID_LENGTH = 128

KEY_CHARACTERS = frozenset("/*$?#")
"""Ids are key segments (``users/<id>``, ``agenda/<id>``): no separator, no wildcard."""

_FORBIDDEN_CATEGORIES = frozenset({"Cc", "Cf", "Cs", "Co", "Cn", "Zl", "Zp"})
"""Control, format, surrogate, private-use, unassigned, line and paragraph separators."""


_PLAIN = re.compile(r"[A-Za-z0-9_.:@ -]*")
"""Printable ASCII without the reserved characters: nothing to look up per character
(most ids; a command id in every robot feedback). ``@`` is checked apart, first only."""


class InvalidIdentifier(ValueError):
    """An identifier broke the rule of this module; the message says how."""


def check_identifier(value: object, what: str = "id") -> str:
    """``value`` trimmed, or :class:`InvalidIdentifier` naming ``what`` and the fault."""
    if not isinstance(value, str):
        raise InvalidIdentifier(f"{what}: must be a string (got {type(value).__name__})")
    trimmed = value.strip()
    fault = _fault(trimmed)
    if fault is not None:
        raise InvalidIdentifier(f"{what}: {fault}")
    return trimmed


def _fault(trimmed: str) -> str | None:
    if not trimmed:
        return "must not be empty or only white space"
    if len(trimmed) > MAX_ID_LENGTH:
        return f"longer than {MAX_ID_LENGTH} characters"
    if trimmed.startswith("@"):
        return "starts with '@', which Zenoh keeps for verbatim chunks (no query reaches it)"
    if _PLAIN.fullmatch(trimmed):
        return None
    for char in trimmed:
        if unicodedata.category(char) in _FORBIDDEN_CATEGORIES:
            return f"holds the control or format character U+{ord(char):04X}"
        if char in KEY_CHARACTERS:
            return f"holds {char!r}, which Zenoh keys reserve"
    return None


def _validate(value: str) -> str:
    trimmed = value.strip()
    fault = _fault(trimmed)
    if fault is not None:
        raise ValueError(fault)
    return trimmed


Identifier = Annotated[
    str,
    StringConstraints(max_length=4 * MAX_ID_LENGTH),
    AfterValidator(_validate),
]
"""A pydantic field type for identifiers (see the module docstring)."""


def printable(text: str, limit: int = 200) -> str:
    """``text`` safe for one console or log line: control characters escaped, cut at ``limit``.

    For free text from other processes (a request's ``by``, an utterance) that is
    printed: a newline in it must not forge a line of the log.
    """
    out = []
    for char in text[:limit]:
        if unicodedata.category(char) in _FORBIDDEN_CATEGORIES:
            out.append(char.encode("unicode_escape").decode("ascii"))
        else:
            out.append(char)
    return "".join(out) + ("…" if len(text) > limit else "")
