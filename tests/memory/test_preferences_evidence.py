"""What the chooser learns from a user's own evidence.

A rating says how much; a completion only that the user did not stop it; a
cancellation that they probably disliked it. The chooser's belief about each activity
weighs them so, over the prediction from features.
"""

from __future__ import annotations

import random
import statistics

from dms.kernel.activity_names import ENTERTAINMENT_ACTIVITIES
from memory import ActivityChooser, PreferenceModel
from memory.profile import ActivityScore, Profile
from memory.seed_data import make_personas
from sim.study import kendall_tau
from tests.memory.conftest import NOW


def _profile(scores: dict[str, ActivityScore], **fields: object) -> Profile:
    return Profile.model_validate(
        {"user_id": "ann", "created_at": NOW, "updated_at": NOW, "scores": scores, **fields}
    )


def _means(chooser: ActivityChooser, profile: Profile) -> dict[str, float]:
    return {name: a / (a + b) for name, (a, b) in chooser.beliefs(profile).items()}


CHOOSER = ActivityChooser(PreferenceModel.from_seed())
EXPLORER = ActivityChooser(PreferenceModel.from_seed(), policy="explore")


def test_a_rating_outweighs_any_number_of_completions() -> None:
    profile = _profile(
        {
            # done six times, never stopped, but rated 2 of 5 twice
            "quiz": ActivityScore(completions=6, feedback_count=2, feedback_sum=0.5),
            # done twice and rated 5 of 5 both times
            "bingo": ActivityScore(completions=2, feedback_count=2, feedback_sum=2.0),
            # done six times, never rated
            "news": ActivityScore(completions=6),
        }
    )
    means = _means(CHOOSER, profile)
    assert means["bingo"] > means["news"] > means["quiz"]
    assert means["quiz"] < means["jokes"]  # liked less than one nothing is known of
    assert means["jokes"] == means["dance"]  # no features, no evidence: the same belief


def test_cancellations_sink_an_activity_completions_keep_it_up() -> None:
    profile = _profile(
        {"quiz": ActivityScore(cancellations=3), "bingo": ActivityScore(completions=3)}
    )
    means = _means(CHOOSER, profile)
    assert means["quiz"] < 0.3 < 0.5 < means["bingo"]
    assert CHOOSER.ranking(profile, random.Random(0))[-1] == "quiz"


def test_one_rating_of_each_activity_ranks_them_as_the_user_does() -> None:
    rng = random.Random(5)
    taus = []
    for _ in range(30):
        liking = {name: rng.random() for name in ENTERTAINMENT_ACTIVITIES}
        scores = {
            name: ActivityScore(
                completions=1,
                feedback_count=1,
                feedback_sum=min(4, max(0, round(4 * value + rng.gauss(0, 0.4)))) / 4,
            )
            for name, value in liking.items()
        }
        truth = sorted(liking, key=lambda name: -liking[name])
        taus.append(kendall_tau(CHOOSER.ranking(_profile(scores), rng), truth))
    assert statistics.fmean(taus) >= 0.7


def test_thompson_draws_follow_the_evidence() -> None:
    profile = _profile(
        {
            "bingo": ActivityScore(completions=4, feedback_count=4, feedback_sum=3.75),
            **{
                name: ActivityScore(completions=1, cancellations=2, feedback_count=1)
                for name in ENTERTAINMENT_ACTIVITIES
                if name != "bingo"
            },
        }
    )
    rng = random.Random(1)
    picks = [CHOOSER.choose(profile, rng).activity for _ in range(200)]
    assert picks.count("bingo") >= 180
    assert {CHOOSER.choose(profile, rng, exclude={"bingo"}).activity for _ in range(50)} != {
        "bingo"
    }


def test_early_on_it_tries_several_activities() -> None:
    """Thompson sampling and the novelty picks explore: over the first 20 choices for a
    new user who rates each one as they like it, several activities get tried."""
    tried = []
    for seed, persona in enumerate(make_personas(40, seed=77)):
        rng = random.Random(seed)
        scores: dict[str, ActivityScore] = {}
        picks = []
        for _ in range(20):
            name = EXPLORER.choose(_profile(scores, age=persona.features["age"]), rng).activity
            picks.append(name)
            old = scores.get(name, ActivityScore())
            scores[name] = ActivityScore(
                feedback_sum=old.feedback_sum + persona.liking[name],
                feedback_count=old.feedback_count + 1,
            )
        tried.append(len(set(picks)))
    assert statistics.fmean(tried) >= 5
    assert sum(count >= 4 for count in tried) >= 36  # nine in ten
