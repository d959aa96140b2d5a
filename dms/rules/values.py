"""Run-time values of DMSL: numbers, strings, booleans and sets; ``None`` is *unknown*.

A boolean is not a number here (Python says ``True == 1``; DMSL does not), so sets keep
their numbers, strings and booleans apart.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from enum import StrEnum
from numbers import Real
from typing import Any


class Kind(StrEnum):
    """The kind of a value; the names are the parameter schema's type names."""

    NUMBER = "number"
    STRING = "string"
    BOOLEAN = "boolean"
    SET = "set"


@dataclass(frozen=True, slots=True)
class DmslSet:
    """A set of literals, one frozenset per kind so that ``true`` never equals ``1``."""

    numbers: frozenset[int | float] = frozenset()
    strings: frozenset[str] = frozenset()
    booleans: frozenset[bool] = frozenset()

    @classmethod
    def of(cls, items: Iterable[Value]) -> DmslSet | None:
        """The set of ``items``; ``None`` when one of them is not a literal."""
        numbers: set[int | float] = set()
        strings: set[str] = set()
        booleans: set[bool] = set()
        for item in items:
            kind = kind_of(item)
            if kind is Kind.BOOLEAN:
                booleans.add(bool(item))
            elif kind is Kind.NUMBER:
                numbers.add(item)  # type: ignore[arg-type]
            elif kind is Kind.STRING:
                strings.add(item)  # type: ignore[arg-type]
            else:
                return None
        return cls(frozenset(numbers), frozenset(strings), frozenset(booleans))

    def kinds(self) -> frozenset[Kind]:
        """The kinds of the elements."""
        found = set()
        if self.numbers:
            found.add(Kind.NUMBER)
        if self.strings:
            found.add(Kind.STRING)
        if self.booleans:
            found.add(Kind.BOOLEAN)
        return frozenset(found)

    def contains(self, value: Value) -> bool | None:
        """Membership; unknown (``None``) for a value that cannot be an element."""
        kind = kind_of(value)
        if kind is Kind.NUMBER:
            return value in self.numbers
        if kind is Kind.STRING:
            return value in self.strings
        if kind is Kind.BOOLEAN:
            return value in self.booleans
        return None


Value = int | float | str | bool | DmslSet | None


def kind_of(value: object) -> Kind | None:
    """The kind of a normalized value; ``None`` for unknown."""
    kind = type(value)
    if kind is bool:
        return Kind.BOOLEAN
    if kind is int or kind is float:
        return Kind.NUMBER
    if kind is str:
        return Kind.STRING
    if kind is DmslSet:
        return Kind.SET
    return None


UNUSABLE = object()
"""A parameter value the rules cannot use (a mapping, a list of mappings, ...)."""


def normalize(value: Any) -> Value | object:
    """A caller's parameter value as a DMSL value; ``UNUSABLE`` when it cannot be one.

    Numbers of any numeric type become int or float; lists, tuples and sets become
    :class:`DmslSet`.
    """
    if isinstance(value, bool):
        return bool(value)
    if isinstance(value, str):
        return str(value)
    if isinstance(value, int):
        return int(value)
    if isinstance(value, Real):
        return float(value)
    if isinstance(value, list | tuple | set | frozenset):
        normalized = [normalize(item) for item in value]
        if any(item is UNUSABLE or item is None or type(item) is DmslSet for item in normalized):
            return UNUSABLE
        made = DmslSet.of(normalized)  # type: ignore[arg-type]
        return UNUSABLE if made is None else made
    return UNUSABLE
