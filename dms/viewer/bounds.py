"""How much the viewer keeps: per message, per key and per robot.

The viewer listens to whatever reaches its Zenoh session, and stays open for days: no
peer may make it grow without end. A message is measured by the length of its JSON;
one over :data:`MAX_MESSAGE_CHARS` is not kept whole (a decision keeps its few short
fields and says how large it was, anything else is left out with a notice on the page).
The decisions and the errors of a robot are each kept up to a count and a total size,
the oldest going first.
"""

from __future__ import annotations

import json
import sys
from collections import deque
from collections.abc import Iterable, Iterator, Mapping
from typing import Any

MAX_READ_BYTES = 256 * 1024
"""A payload larger than this is not even parsed (the source says so instead)."""
MAX_MESSAGE_CHARS = 64 * 1024
"""A state, a decision or an error whose JSON is longer is not kept whole."""
MAX_STRUCTURE_CHARS = 256 * 1024
"""A behavior's structure longer than this is not drawn (the page says why)."""
DECISIONS_BUDGET_CHARS = 1024 * 1024
"""The decisions kept per robot, all together (besides their count)."""
ERRORS_BUDGET_CHARS = 256 * 1024
"""The errors kept per robot, all together (besides their count)."""
MAX_SERIES = 16
"""Drives (and motivations) charted per robot: the paper's robot has three."""
MAX_NAME_CHARS = 64
MAX_TEXT_CHARS = 2000
"""An error's text, a decision's detail: longer is cut (with an ellipsis)."""
MAX_TOKENS = 64
"""Liveliness tokens kept per robot."""
MAX_AGENDA_ITEMS = 20
"""Agenda items kept per robot (the page shows ten)."""
DECISION_FIELDS = ("tick", "time", "action", "activity", "reason", "chosen_by", "detail")
"""What an oversized decision keeps."""


def json_size(value: Any) -> int:
    """The length of ``value``'s JSON (what the page is sent), or a huge number when it
    is not plain JSON."""
    try:
        return len(json.dumps(value, separators=(",", ":"), allow_nan=False))
    except (TypeError, ValueError, RecursionError):
        return sys.maxsize


def short(text: str, limit: int = MAX_TEXT_CHARS) -> str:
    return text if len(text) <= limit else text[: limit - 1] + "…"


def interned(text: str) -> str:
    """A series, activity or drive name, cut and interned (kept once for every sample)."""
    return sys.intern(text[:MAX_NAME_CHARS])


def small_decision(decision: Mapping[str, Any], size: int) -> dict[str, Any]:
    """What is kept of a decision whose JSON is ``size`` characters, over the limit: its
    short fields, and ``oversized`` (the page says the rest was left out)."""
    kept: dict[str, Any] = {"oversized": size}
    for field in DECISION_FIELDS:
        value = decision.get(field)
        if isinstance(value, str):
            kept[field] = short(value, MAX_TEXT_CHARS if field == "detail" else MAX_NAME_CHARS)
        elif isinstance(value, int | float | bool) or value is None:
            kept[field] = value
    return kept


def bounded_decision(decision: dict[str, Any]) -> tuple[dict[str, Any], int]:
    """``decision`` and its JSON size, or its short fields when it is too large to keep."""
    size = json_size(decision)
    if size <= MAX_MESSAGE_CHARS:
        return decision, size
    small = small_decision(decision, size)
    return small, json_size(small)


def small_report(report: Mapping[str, Any]) -> dict[str, str]:
    """What is kept of a ``dms/errors`` message: its key, text and time, cut short."""
    return {
        part: short(value, MAX_TEXT_CHARS if part == "error" else 4 * MAX_NAME_CHARS)
        for part in ("key", "error", "time")
        if isinstance(value := report.get(part), str)
    }


def small_agenda(agenda: Mapping[str, Any]) -> dict[str, Any]:
    """The first :data:`MAX_AGENDA_ITEMS` items of an agenda reply (none over 4 kB), or
    its error."""
    items = agenda.get("items")
    if isinstance(items, list):
        return {"items": [i for i in items[:MAX_AGENDA_ITEMS] if json_size(i) < 4096]}
    error = agenda.get("error")
    return {"error": short(error) if isinstance(error, str) else "not understood"}


def size_text(chars: int) -> str:
    return f"{chars / 1024:.0f} kB" if chars < 1024 * 1024 else f"{chars / 1048576:.1f} MB"


class BoundedLog:
    """The newest items, at most ``count`` of them and ``budget`` characters of JSON."""

    def __init__(self, count: int, budget: int) -> None:
        self._items: deque[tuple[dict[str, Any], int]] = deque()
        self._count = count
        self._budget = budget
        self._chars = 0

    def append(self, item: dict[str, Any], size: int | None = None) -> None:
        """Add ``item`` (its JSON ``size``, when known); the oldest make room."""
        size = json_size(item) if size is None else size
        self._items.append((item, size))
        self._chars += size
        while self._items and (len(self._items) > self._count or self._chars > self._budget):
            self._chars -= self._items.popleft()[1]

    def replace(self, items: Iterable[dict[str, Any]]) -> None:
        self._items.clear()
        self._chars = 0
        for item in items:
            self.append(item)

    @property
    def chars(self) -> int:
        return self._chars

    def __iter__(self) -> Iterator[dict[str, Any]]:
        return (item for item, _size in self._items)

    def __len__(self) -> int:
        return len(self._items)
