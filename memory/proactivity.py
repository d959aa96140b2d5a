"""The user's proactivity, estimated from what the user does with the initiative.

A *chance* is a moment where the user could take the initiative: the robot offers it
(the menu, "what shall we do?") and the user chooses (taken) or declines or lets it
pass (not taken); or the user takes it unprompted (asks for an activity by voice or on
the screen, stops one with the shoulder): a chance taken. The robot's own choices are
not chances: counting them would make the estimate follow the mode it chose, and the
modes collapse.

The rate of chances taken has a Beta posterior whose prior comes from the user's answer
to the general question on initiative (``robot_initiative_frequency``: a user who wants
the robot to start often is less proactive), worth :data:`PRIOR_WEIGHT` chances. The
record is recent: past :data:`WINDOW` chances both counts are halved, so old habits
fade. The level is the posterior mean cut in thirds, with :data:`HYSTERESIS` around each
cut so that one chance does not flip the mode.

Pure: no database, no clock.
"""

from __future__ import annotations

import math

WINDOW = 20
"""Chances remembered at full weight; past twice this, both counts are halved."""
PRIOR_WEIGHT = 6.0
"""How many chances the answer to the question on initiative is worth: about two
sessions of menus, so that what the user said is not overturned by the first few
choices of their first session (the mode follows the estimate from the first choice
on), while a few sessions of behavior do overturn it."""
MIN_CHANCES = 3
"""Without an answer, chances needed before the level leaves ``unknown``."""
HYSTERESIS = 0.05
"""How far past a cut (1/3, 2/3) the mean must go to change the level."""

_PRIOR_RATE = {"low": 0.8, "moderate": 0.5, "high": 0.2}
"""``robot_initiative_frequency`` answer -> the user's prior rate of taking the initiative."""
_CUTS = (1 / 3, 2 / 3)
_LEVELS = ("low", "moderate", "high")
_UNIFORM_SD = math.sqrt(1 / 12)


def forget(taken: int, offered: int) -> tuple[int, int]:
    """The counts after one more chance was added: halved once past twice the window."""
    if offered > 2 * WINDOW:
        return taken // 2, offered // 2
    return taken, offered


def estimate(
    taken: int, offered: int, robot_initiative: str | None, previous: str = "unknown"
) -> tuple[str, float]:
    """Level (``low``/``moderate``/``high``/``unknown``) and confidence in [0, 1].

    ``previous`` is the level in force (for the hysteresis); ``robot_initiative`` the
    answer to the question on initiative, or None.
    """
    prior = _PRIOR_RATE.get(robot_initiative or "")
    a0, b0 = (PRIOR_WEIGHT * prior, PRIOR_WEIGHT * (1 - prior)) if prior is not None else (1.0, 1.0)
    a = a0 + taken
    b = b0 + max(0, offered - taken)
    mean = a / (a + b)
    sd = math.sqrt(a * b / ((a + b) ** 2 * (a + b + 1)))
    confidence = round(max(0.0, 1.0 - sd / _UNIFORM_SD), 4)
    if prior is None and offered < MIN_CHANCES:
        return "unknown", confidence
    return _level(mean, previous), confidence


def _level(mean: float, previous: str) -> str:
    plain = _LEVELS[sum(mean >= cut for cut in _CUTS)]
    if previous not in _LEVELS or plain == previous:
        return plain
    index = _LEVELS.index(previous)
    low_edge = _CUTS[index - 1] - HYSTERESIS if index > 0 else -math.inf
    high_edge = _CUTS[index] + HYSTERESIS if index < len(_CUTS) else math.inf
    return previous if low_edge <= mean < high_edge else plain
