"""The activity catalogue: the sixteen shipped activities of docs/contract.md and the ones
designers declare in behavior files, each with the manager it belongs to.

The catalogue in force is one immutable :class:`Catalogue`. The behavior loader builds a
new one from the behaviors folder at start and on every reload and installs it
(:func:`install`); everything else reads it through :data:`ACTIVITIES`,
:data:`ENTERTAINMENT_ACTIVITIES` and :data:`USER_SELECTABLE`, live views of the
catalogue in force, or :func:`current`. Installing is one reference swap, so a reader on
another thread sees the old catalogue or the new one, never half of each.
"""

from __future__ import annotations

import re
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from difflib import get_close_matches
from enum import StrEnum
from typing import overload


class ManagerName(StrEnum):
    """The five managers of the paper's manager level."""

    ENTERTAINMENT = "entertainment"
    SOCIAL = "social"
    RELAX = "relax"
    COGNITIVE = "cognitive"
    GENERAL = "general"


SHIPPED: Mapping[str, ManagerName] = {
    "multimedia": ManagerName.ENTERTAINMENT,
    "news": ManagerName.ENTERTAINMENT,
    "weather": ManagerName.ENTERTAINMENT,
    "quiz": ManagerName.ENTERTAINMENT,
    "dance": ManagerName.ENTERTAINMENT,
    "bingo": ManagerName.ENTERTAINMENT,
    "jokes": ManagerName.ENTERTAINMENT,
    "sayings": ManagerName.ENTERTAINMENT,
    "talk": ManagerName.SOCIAL,
    "presentation": ManagerName.SOCIAL,
    "sleep": ManagerName.RELAX,
    "wait": ManagerName.RELAX,
    "cognitive_stimulation": ManagerName.COGNITIVE,
    "notification": ManagerName.GENERAL,
    "instructions": ManagerName.GENERAL,
    "menu": ManagerName.GENERAL,
}
"""The shipped activities, in docs/contract.md's order, with their managers."""

SHIPPED_ENTERTAINMENT: tuple[str, ...] = tuple(
    name for name, manager in SHIPPED.items() if manager is ManagerName.ENTERTAINMENT
)
"""The shipped entertainment activities: those the preference model ranks from features."""

NOT_SELECTABLE = frozenset({"notification", "menu", "wait", "sleep"})
"""Shipped activities the robot runs by itself, never offered to a user."""

DECLARABLE_MANAGERS = (
    ManagerName.ENTERTAINMENT,
    ManagerName.COGNITIVE,
    ManagerName.SOCIAL,
    ManagerName.RELAX,
)
"""The managers a declared activity may belong to (the general manager's activities,
notifications, instructions and the menu, are the robot's own)."""

MAX_NAME_CHARS = 40
MAX_SHOWN_CHARS = 120
"""How much of an unknown name a refusal quotes."""
NAME_PATTERN = re.compile(r"^[a-z][a-z0-9_]{0,39}$")
"""A declared activity's name: what a request, a rule and a stored row can carry."""

TWIN_CUTOFF = 0.8
"""How alike (difflib's ratio) a name and a shipped one are when one is a typo of the
other: ``jokez`` for ``jokes``. A declared activity is never so close to a shipped one,
so ``dms request`` can refuse such a typo before asking the daemon."""

MAX_DECLARED = 64
"""Declared activities in force at most: the menu, the chooser and each question's
choices stay short enough to show and to learn."""


@dataclass(frozen=True, slots=True)
class ActivityEntry:
    """One activity of the catalogue: what the robot needs to run, offer and choose it."""

    name: str
    manager: ManagerName
    label: str = ""
    """The name shown on the menu ("" : the activity's name)."""
    picture: str | None = None
    """An image file shown beside it on the menu."""
    expected_s: float | None = None
    """How long it usually lasts, in seconds (None: not said)."""
    features: Mapping[str, tuple[str | int | bool, ...]] = field(default_factory=dict)
    """The user features that make a first guess that someone likes it: a feature's name
    (one the preference model learns from) and the values that suggest it."""
    pausable: bool = True
    """False: a pause (a reminder, the shoulder, a request) stops it instead."""
    shipped: bool = False


class Catalogue:
    """The activities in force: the shipped ones, then the declared ones in name order."""

    def __init__(self, declared: Sequence[ActivityEntry] = ()) -> None:
        entries = [ActivityEntry(n, m, shipped=True) for n, m in SHIPPED.items()]
        extra = sorted((e for e in declared if e.name not in SHIPPED), key=lambda entry: entry.name)
        entries.extend(extra[:MAX_DECLARED])
        self.entries: Mapping[str, ActivityEntry] = {e.name: e for e in entries}
        self.managers: Mapping[str, ManagerName] = {e.name: e.manager for e in entries}
        self.entertainment: tuple[str, ...] = tuple(
            e.name for e in entries if e.manager is ManagerName.ENTERTAINMENT
        )
        self.user_selectable: tuple[str, ...] = tuple(
            e.name for e in entries if e.name not in NOT_SELECTABLE
        )
        self.declared: tuple[ActivityEntry, ...] = tuple(e for e in entries if not e.shipped)

    def entry(self, name: str) -> ActivityEntry | None:
        return self.entries.get(name)

    def unknown(self, name: str) -> str:
        """The one line saying ``name`` is no activity here, with the nearest one (a name
        over :data:`MAX_SHOWN_CHARS` is cut, and not compared: it is no typo)."""
        if len(name) > MAX_SHOWN_CHARS:
            cut = name[:MAX_SHOWN_CHARS]
            return f"unknown activity {cut!r}... (names are at most {MAX_NAME_CHARS} characters)"
        close = get_close_matches(name, list(self.managers), n=1)
        hint = f"; did you mean {close[0]}?" if close else f"; one of {', '.join(self.managers)}"
        return f"unknown activity {name!r}{hint}"


_current = Catalogue()


def current() -> Catalogue:
    """The catalogue in force."""
    return _current


def install(catalogue: Catalogue) -> None:
    """Put ``catalogue`` in force (the behavior loader, at start and on a reload)."""
    global _current
    _current = catalogue


class _LiveManagers(Mapping[str, ManagerName]):
    """Every activity name in force with its manager (reads :func:`current` each time)."""

    def __getitem__(self, name: str) -> ManagerName:
        return _current.managers[name]

    def __iter__(self) -> Iterator[str]:
        return iter(_current.managers)

    def __len__(self) -> int:
        return len(_current.managers)

    def __contains__(self, name: object) -> bool:
        return name in _current.managers


class _LiveNames(Sequence[str]):
    """A tuple of names of the catalogue in force (reads :func:`current` each time)."""

    def __init__(self, attribute: str) -> None:
        self._attribute = attribute

    def _names(self) -> tuple[str, ...]:
        names: tuple[str, ...] = getattr(_current, self._attribute)
        return names

    @overload
    def __getitem__(self, index: int) -> str: ...
    @overload
    def __getitem__(self, index: slice) -> Sequence[str]: ...
    def __getitem__(self, index: int | slice) -> str | Sequence[str]:
        return self._names()[index]

    def __len__(self) -> int:
        return len(self._names())

    def __iter__(self) -> Iterator[str]:
        return iter(self._names())

    def __contains__(self, name: object) -> bool:
        return name in self._names()

    def __repr__(self) -> str:
        return repr(self._names())


ACTIVITIES: Mapping[str, ManagerName] = _LiveManagers()
"""Every activity name in force, shipped first in docs/contract.md's order, with its
manager."""

ENTERTAINMENT_ACTIVITIES: Sequence[str] = _LiveNames("entertainment")
"""The entertainment activities in force: what the autonomous choice chooses among."""

USER_SELECTABLE: Sequence[str] = _LiveNames("user_selectable")
"""Activities a user may ask for by name or choose from the menu."""


def manager_of(activity: str) -> ManagerName:
    """The manager of ``activity``; raises KeyError for an unknown name."""
    return _current.managers[activity]
