"""Each random draw behind the robot's choice of an activity, as its ``why`` names it."""

from __future__ import annotations

import random
from collections.abc import Collection
from datetime import UTC, datetime

import pytest

from dms.controller.decisions import choice_why
from dms.kernel.activity_names import ENTERTAINMENT_ACTIVITIES
from memory.preferences import (
    NOVELTY_PROBABILITY,
    ActivityChooser,
    ChoiceDraw,
    PreferenceModel,
)
from memory.profile import ActivityScore, Profile

NOW = datetime(2026, 11, 23, 10, 0, tzinfo=UTC)


def _profile(tried: Collection[str] = ()) -> Profile:
    scores = {
        name: ActivityScore(completions=2, feedback_sum=0.8, feedback_count=1) for name in tried
    }
    return Profile(
        user_id="ann", created_at=NOW, updated_at=NOW, age=80, sex="female", scores=scores
    )


def _chooser() -> ActivityChooser:
    """The exploring chooser, whose draws these tests explain (``[controller] chooser``)."""
    return ActivityChooser(PreferenceModel.from_seed(), policy="explore")


def _reference_choice(
    chooser: ActivityChooser, profile: Profile, rng: random.Random, exclude: Collection[str]
) -> str:
    """The choice as the chooser draws it, without keeping what drew it."""
    names = [n for n in ENTERTAINMENT_ACTIVITIES if n not in exclude] or list(
        ENTERTAINMENT_ACTIVITIES
    )
    untried = [n for n in names if n not in profile.scores]
    if untried and rng.random() < NOVELTY_PROBABILITY:
        return rng.choice(untried)
    beliefs = chooser.beliefs(profile)
    draws = {n: rng.betavariate(*beliefs[n]) for n in names}
    return max(names, key=lambda n: draws[n])


@pytest.mark.parametrize("tried", [(), ("quiz", "bingo"), ENTERTAINMENT_ACTIVITIES])
def test_keeping_the_draw_leaves_the_random_stream_as_it_was(tried: tuple[str, ...]) -> None:
    chooser, profile = _chooser(), _profile(tried)
    for seed in range(60):
        exclude = {ENTERTAINMENT_ACTIVITIES[seed % 8]}
        mine, theirs = random.Random(seed), random.Random(seed)
        assert chooser.choose(profile, mine, exclude).activity == _reference_choice(
            chooser, profile, theirs, exclude
        )
        assert mine.getstate() == theirs.getstate()


def test_a_novelty_pick_is_named_with_its_coin_under_the_threshold() -> None:
    chooser = _chooser()
    seeds = [s for s in range(100) if random.Random(s).random() < NOVELTY_PROBABILITY]
    draw = chooser.choose(_profile(("bingo", "dance")), random.Random(seeds[0]), {"quiz"})
    pick, why = draw.activity, choice_why({"quiz"}, draw)
    assert why.by == "novelty" and why.samples is None
    assert why.novelty is not None and why.novelty.draw < why.novelty.probability
    assert why.novelty.probability == NOVELTY_PROBABILITY
    assert pick in why.novelty.untried and not {"bingo", "dance", "quiz"} & set(why.novelty.untried)
    assert why.excluded == ["quiz"] and "quiz" not in why.candidates


def test_a_sampled_pick_is_named_with_every_sample_and_the_coin_it_beat() -> None:
    chooser = _chooser()
    seeds = [s for s in range(100) if random.Random(s).random() >= NOVELTY_PROBABILITY]
    draw = chooser.choose(_profile(("bingo",)), random.Random(seeds[0]), {"quiz"})
    pick, why = draw.activity, choice_why({"quiz"}, draw)
    assert why.by == "sampling"
    assert why.novelty is not None and why.novelty.draw >= why.novelty.probability
    assert why.samples is not None and set(why.samples) == set(why.candidates)
    assert why.samples[pick] == max(why.samples.values())


def test_with_every_activity_tried_no_novelty_coin_is_tossed() -> None:
    chooser = _chooser()
    draw = chooser.choose(_profile(ENTERTAINMENT_ACTIVITIES), random.Random(3))
    pick, why = draw.activity, choice_why((), draw)
    assert why.by == "sampling" and why.novelty is None and why.excluded is None
    assert why.samples is not None and why.samples[pick] == max(why.samples.values())
    assert "novelty" not in why.model_dump() and "excluded" not in why.model_dump()


def test_every_choice_returns_its_own_draw_and_keeps_none() -> None:
    chooser, profile = _chooser(), _profile()
    rng = random.Random(1)
    first, second = chooser.choose(profile, rng), chooser.choose(profile, rng)
    assert isinstance(first, ChoiceDraw) and first is not second
    assert not hasattr(chooser, "last_draw"), "the draw is returned, not left to compare"


def test_a_pick_without_the_chooser_is_named_uniform_or_the_other_choosers() -> None:
    uniform = choice_why({"quiz"}, None)
    assert uniform.by == "random" and uniform.candidates == [
        n for n in ENTERTAINMENT_ACTIVITIES if n != "quiz"
    ]
    baseline = ChoiceDraw("bingo", ENTERTAINMENT_ACTIVITIES, (), None, None, explained=False)
    other = choice_why((), baseline)
    assert other.by == "chooser" and other.candidates == list(ENTERTAINMENT_ACTIVITIES)
    assert other.novelty is None and other.samples is None
