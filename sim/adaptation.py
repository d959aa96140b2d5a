"""How well the robot knows each participant: Kendall's tau against two baselines.

After each visit the daemon's predicted ranking of the entertainment activities (its
chooser's expected liking) is compared with the participant's hidden true ranking, and
so are two rankings that learnt nothing from the visits:

- ``population``: one ranking for everyone, the activities' mean position in the
  learner's training data (``memory/data/seed_rankings.csv``);
- ``features``: the learner's prediction from the participant's features alone (what it
  knows after the opening questions, before any rating).

On the ``paper`` population the features carry the taste (they come from the training
data's own generator), so most of the tau is there before the first rating; the
``heldout`` population's features say nothing of it, and only the visits can.
"""

from __future__ import annotations

import functools
import random
import statistics
from collections.abc import Sequence
from typing import TYPE_CHECKING

from dms.kernel.activity_names import ENTERTAINMENT_ACTIVITIES, SHIPPED_ENTERTAINMENT

if TYPE_CHECKING:
    from sim.harness import Simulation
    from sim.table4 import SessionMetrics


def kendall_tau(predicted: list[str], truth: list[str]) -> float:
    """Kendall's tau between two rankings of the same activities (scipy.stats.kendalltau
    on each activity's position)."""
    from scipy.stats import kendalltau

    names = [name for name in truth if name in predicted]
    result = kendalltau([predicted.index(n) for n in names], list(range(len(names))))
    value = float(result.statistic)
    return 0.0 if value != value else value  # nan (constant ranking): no agreement


def predicted_ranking(sim: Simulation, user_id: str) -> list[str] | None:
    """The daemon's ranking of the entertainment activities for ``user_id`` now (the
    chooser's expected liking), or None without memory."""
    from memory.errors import ProfileNotFound

    store, chooser = sim.stack.store, sim.stack.chooser
    if store is None or chooser is None:
        return None
    try:
        profile = store.get(user_id)
    except ProfileNotFound:
        return None  # a session too short to meet the participant
    return chooser.ranking(profile, random.Random(0))


def features_ranking(sim: Simulation, user_id: str) -> list[str] | None:
    """The learner's ranking from ``user_id``'s stored features alone (no evidence)."""
    from memory.errors import ProfileNotFound

    store, chooser = sim.stack.store, sim.stack.chooser
    if store is None or chooser is None:
        return None
    try:
        profile = store.get(user_id)
    except ProfileNotFound:
        return None
    scores = chooser.model.win_scores(profile.features())
    if scores is None:
        return None
    names = list(ENTERTAINMENT_ACTIVITIES)
    random.Random(0).shuffle(names)
    return sorted(names, key=lambda name: -scores.get(name, 0.5))


@functools.cache
@functools.cache
def population_ranking() -> tuple[str, ...]:
    """The activities by mean position in the learner's training data, best first."""
    from memory.preferences import load_seed

    totals = dict.fromkeys(SHIPPED_ENTERTAINMENT, 0.0)  # the seed rated these
    for _features, liking in load_seed():
        for name in totals:
            totals[name] += liking.get(name, 0.0)
    return tuple(sorted(totals, key=lambda name: -totals[name]))


def by_visit(sessions: Sequence[SessionMetrics], repeat: int) -> dict[str, list[float]]:
    """Per visit (1..repeat), means over participants: Kendall's tau of the daemon's
    ranking and of the two baselines, cancels of robot-chosen activities (per session
    and per robot choice) and the true liking of the robot's choices."""
    out: dict[str, list[float]] = {
        "kendall_tau_by_session": [],
        "tau_features_by_session": [],
        "tau_population_by_session": [],
        "robot_choice_cancels_by_session": [],
        "cancels_per_robot_choice_by_session": [],
        "robot_choice_liking_by_session": [],
    }
    for visit in range(1, repeat + 1):
        rows = [s for s in sessions if s.visit == visit]
        choices = sum(s.robot_decisions for s in rows)
        likings = [v for s in rows for v in s.robot_choice_liking]
        out["kendall_tau_by_session"].append(_mean([s.kendall_tau for s in rows]))
        out["tau_features_by_session"].append(_mean([s.tau_features for s in rows]))
        out["tau_population_by_session"].append(_mean([s.tau_population for s in rows]))
        out["robot_choice_cancels_by_session"].append(
            _mean([float(s.robot_choice_cancels) for s in rows])
        )
        out["cancels_per_robot_choice_by_session"].append(
            round(sum(s.robot_choice_cancels for s in rows) / choices, 3) if choices else 0.0
        )
        out["robot_choice_liking_by_session"].append(_mean(likings))
    return out


def _mean(values: Sequence[float | None]) -> float:
    present = [v for v in values if v is not None]
    return round(statistics.fmean(present), 3) if present else 0.0
