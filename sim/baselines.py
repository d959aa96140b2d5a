"""Baseline activity choosers for the study, injected in place of the daemon's.

``dms sim study --chooser`` replaces what the robot picks when it chooses on its own
(the controller asks its :class:`memory.ActivityChooser` ``choose``): the decision
system's learned choice as configured (``dms``: by default the paper's, the best of the
predicted ranking), the same with its exploring policy (``explore``: novelty draws and
Thompson sampling, ``[controller] chooser = "explore"``), or a baseline that shows what
the learning adds:

- ``random``: any activity, uniformly;
- ``fixed``: the activities in a fixed cycle, the same for everyone;
- ``popular``: the activity the learner's training data likes best that was not just
  done, the same for everyone (what a designer would ship without any learning);
- ``greedy``: the daemon's own learned ranking, its best (expected liking) that was not
  just done, with no random draw (the paper's policy, put in as a baseline: the same
  picks as ``dms`` on its default settings);
- ``least_liked``: the participant's true worst (a floor: it reads the hidden truth);
- ``oracle``: the participant's true favourite (a ceiling: it reads the hidden truth).

Everything else (the daemon's rankings, learning from ratings, who chooses) is the
daemon's own: :class:`BaselineChooser` delegates every other call to the real chooser.
The controller is not touched; :func:`install` swaps the chooser the controller's
dependencies hold, as the daemon's assembly would wire another one.
"""

from __future__ import annotations

import random
from collections.abc import Callable, Collection
from typing import TYPE_CHECKING, Literal

from dms.kernel.activity_names import ENTERTAINMENT_ACTIVITIES
from memory.preferences import ChoiceDraw
from sim.adaptation import population_ranking

if TYPE_CHECKING:
    from dms.config import Settings
    from memory import ActivityChooser
    from memory.profile import Profile
    from sim.harness import Simulation

ChooserName = Literal[
    "dms", "explore", "random", "fixed", "popular", "greedy", "least_liked", "oracle"
]
CHOOSERS: tuple[ChooserName, ...] = (
    "dms",
    "explore",
    "random",
    "fixed",
    "popular",
    "greedy",
    "least_liked",
    "oracle",
)
BASELINES: tuple[ChooserName, ...] = CHOOSERS[1:]
Truth = Callable[[str], dict[str, float] | None]
"""A participant's hidden liking of each activity, by user id (None: unknown)."""


class BaselineChooser:
    """The daemon's chooser with ``choose`` replaced by a baseline's pick."""

    def __init__(self, inner: ActivityChooser, name: ChooserName, truth: Truth, seed: int) -> None:
        self.inner = inner
        self.name = name
        self.truth = truth
        self.rng = random.Random(f"chooser/{name}/{seed}")
        """The baseline's own draws: the controller's random stream is left as it is."""
        self._turn = 0

    def __getattr__(self, attribute: str) -> object:
        return getattr(self.inner, attribute)

    def choose(
        self, profile: Profile, rng: random.Random, exclude: Collection[str] = ()
    ) -> ChoiceDraw:
        """One entertainment activity not in ``exclude``, by the baseline's rule; its
        draws are its own (the decision's ``why`` names none)."""
        names = [n for n in ENTERTAINMENT_ACTIVITIES if n not in exclude] or list(
            ENTERTAINMENT_ACTIVITIES
        )
        pick = self._pick(profile, names)
        return ChoiceDraw(pick, tuple(names), (), None, None, explained=False)

    def _pick(self, profile: Profile, names: list[str]) -> str:
        if self.name == "random":
            return self.rng.choice(names)
        if self.name == "fixed":
            while True:
                pick = ENTERTAINMENT_ACTIVITIES[self._turn % len(ENTERTAINMENT_ACTIVITIES)]
                self._turn += 1
                if pick in names:
                    return pick
        if self.name == "popular":
            return next(name for name in population_ranking() if name in names)
        if self.name == "greedy":
            return next(name for name in self.inner.ranking(profile, self.rng) if name in names)
        liking = self.truth(profile.user_id) or {}
        best = sorted(names, key=lambda n: (liking.get(n, 0.5), self.rng.random()))
        return best[0] if self.name == "least_liked" else best[-1]


def settings_for(settings: Settings, name: ChooserName) -> Settings:
    """The study's settings for chooser ``name``: ``explore`` is the daemon's own chooser
    with its exploring policy (``[controller] chooser``); the others leave them as given."""
    if name != "explore":
        return settings
    controller = settings.controller.model_copy(update={"chooser": "explore"})
    return settings.model_copy(update={"controller": controller})


def install(sim: Simulation, name: ChooserName, truth: Truth, seed: int) -> None:
    """Make ``sim``'s controller choose with ``name`` (``dms`` and ``explore``: leave the
    daemon's, as configured)."""
    if name in ("dms", "explore"):
        return
    deps = sim.controller.deps
    if deps.chooser is None:
        raise ValueError("a baseline chooser needs the daemon's memory")
    deps.chooser = BaselineChooser(deps.chooser, name, truth, seed)  # type: ignore[assignment]
