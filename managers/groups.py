"""The five managers of the paper (Fig. 6), one per group of activities.

Four only run their group's activities: social (talk and presentation, the activities
that are conversation), relax (sleep and wait, what the robot does when nothing calls
for it), cognitive (cognitive stimulation sessions) and general (notifications,
instructions and the menu; short communications pause the others). The entertainment
manager also makes a partial decision: which entertainment activity to run.
"""

from __future__ import annotations

import random
from collections.abc import Callable, Collection

from activities import BehaviorLibrary
from dms.kernel.activity_names import ENTERTAINMENT_ACTIVITIES, ManagerName
from managers.base import Manager

EntertainmentChooser = Callable[[random.Random, Collection[str]], str]
"""Picks an entertainment activity for the present user, given what to exclude."""


class EntertainmentManager(Manager):
    """Multimedia, news, weather, quiz, dance, bingo, jokes, sayings.

    It makes the paper's partial decision: which entertainment activity suits this user,
    through the chooser it is given (learned preferences, or a ``ChooseEntertainment`` rule).
    """

    def __init__(self, library: BehaviorLibrary) -> None:
        super().__init__(ManagerName.ENTERTAINMENT, library)

    def choose(
        self,
        rng: random.Random,
        chooser: EntertainmentChooser | None,
        exclude: Collection[str] = (),
    ) -> str:
        if chooser is not None:
            return chooser(rng, exclude)
        options = [name for name in ENTERTAINMENT_ACTIVITIES if name not in exclude]
        return rng.choice(options or list(ENTERTAINMENT_ACTIVITIES))


def make_managers(library: BehaviorLibrary) -> dict[ManagerName, Manager]:
    """One manager of each kind, sharing the behavior library."""
    managers = [
        EntertainmentManager(library),
        Manager(ManagerName.SOCIAL, library),
        Manager(ManagerName.RELAX, library),
        Manager(ManagerName.COGNITIVE, library),
        Manager(ManagerName.GENERAL, library),
    ]
    return {manager.name: manager for manager in managers}
