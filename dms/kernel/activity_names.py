"""The fixed activity names of docs/contract.md and the manager each belongs to."""

from __future__ import annotations

from enum import StrEnum


class ManagerName(StrEnum):
    """The five managers of the paper's manager level."""

    ENTERTAINMENT = "entertainment"
    SOCIAL = "social"
    RELAX = "relax"
    COGNITIVE = "cognitive"
    GENERAL = "general"


ACTIVITIES: dict[str, ManagerName] = {
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
"""Every activity name, in docs/contract.md's order, with its manager."""

ENTERTAINMENT_ACTIVITIES: tuple[str, ...] = tuple(
    name for name, manager in ACTIVITIES.items() if manager is ManagerName.ENTERTAINMENT
)

USER_SELECTABLE: tuple[str, ...] = tuple(
    name for name in ACTIVITIES if name not in ("notification", "menu", "wait", "sleep")
)
"""Activities a user may ask for by name or choose from the menu."""


def manager_of(activity: str) -> ManagerName:
    """The manager of ``activity``; raises KeyError for an unknown name."""
    return ACTIVITIES[activity]
