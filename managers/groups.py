"""The five managers of the paper (Fig. 6), one per group of activities."""

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

    name = ManagerName.ENTERTAINMENT

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


class SocialManager(Manager):
    """Talk and presentation: the activities that are conversation."""

    name = ManagerName.SOCIAL


class RelaxManager(Manager):
    """Sleep and wait: what the robot does when nothing calls for it."""

    name = ManagerName.RELAX


class CognitiveManager(Manager):
    """Cognitive stimulation sessions."""

    name = ManagerName.COGNITIVE


class GeneralManager(Manager):
    """Notifications, instructions and the menu; short communications pause the others."""

    name = ManagerName.GENERAL


def make_managers(library: BehaviorLibrary) -> dict[ManagerName, Manager]:
    """One manager of each kind, sharing the behavior library."""
    managers: list[Manager] = [
        EntertainmentManager(library),
        SocialManager(library),
        RelaxManager(library),
        CognitiveManager(library),
        GeneralManager(library),
    ]
    return {manager.name: manager for manager in managers}
