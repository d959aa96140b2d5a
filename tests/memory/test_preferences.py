"""Preference prediction and choice on simulated personas with known true preferences."""

from __future__ import annotations

import random
import statistics
from collections import Counter
from datetime import timedelta

from dms.kernel.activity_names import ENTERTAINMENT_ACTIVITIES
from memory import ActivityChooser, PreferenceModel, ProfileStore
from memory.seed_data import SEED_CSV, make_personas
from tests.memory.conftest import NOW


def tau(predicted: list[str], truth: list[str]) -> float:
    position = {name: index for index, name in enumerate(truth)}
    order = [position[name] for name in predicted]
    signs = [
        1 if order[i] < order[j] else -1
        for i in range(len(order))
        for j in range(i + 1, len(order))
    ]
    return sum(signs) / len(signs)


def test_the_seed_dataset_ships_and_is_what_the_generator_makes(tmp_path: object) -> None:
    from pathlib import Path

    from memory.seed_data import write_seed_csv

    assert isinstance(tmp_path, Path)
    fresh = tmp_path / "seed.csv"
    write_seed_csv(fresh)
    assert fresh.read_text() == SEED_CSV.read_text()
    assert len(SEED_CSV.read_text().splitlines()) == 401


def test_features_predict_unseen_personas_far_better_than_chance() -> None:
    model = PreferenceModel.from_seed()
    rng = random.Random(5)
    personas = make_personas(150, seed=77)  # not the seed data's personas
    predicted = [tau(model.predict_ranking(p.features, rng), p.ranking()) for p in personas]
    chance = [tau(model.predict_ranking({}, rng), p.ranking()) for p in personas]
    assert statistics.fmean(predicted) > 0.45
    assert abs(statistics.fmean(chance)) < 0.15
    # Partial features still help.
    ages_only = [
        tau(
            model.predict_ranking(
                {"age": p.features["age"], "hobbies": p.features["hobbies"]}, rng
            ),
            p.ranking(),
        )
        for p in personas
    ]
    assert statistics.fmean(chance) + 0.15 < statistics.fmean(ages_only)


def test_no_usable_features_give_a_random_ranking_of_all_eight() -> None:
    model = PreferenceModel.from_seed()
    rankings = {
        tuple(model.predict_ranking(features, random.Random(seed)))
        for seed in range(20)
        for features in ({}, {"favourite_colour": "blue"})
    }
    assert all(sorted(r) == sorted(ENTERTAINMENT_ACTIVITIES) for r in rankings)
    assert len(rankings) > 10
    same = model.predict_ranking({"age": 80, "hobbies": "cards"}, random.Random(1))
    assert same == model.predict_ranking({"age": 80, "hobbies": "cards"}, random.Random(2))
    assert same[0] == "bingo"  # card players love bingo in the simulated world


def _like_only(store: ProfileStore, user: str, favorite: str, count: int) -> None:
    store.get_or_create(user, NOW)
    store.update(user, NOW, age=30, hobbies="reading", sex="male", education="university")
    for activity in ENTERTAINMENT_ACTIVITIES:
        for _ in range(count):
            store.record_feedback(user, activity, 1.0 if activity == favorite else 0.0, NOW)


def test_training_learns_from_stored_users_and_forgets_erased_ones(store: ProfileStore) -> None:
    rng = random.Random(0)
    features = {"age": 30, "hobbies": "reading", "sex": "male", "education": "university"}
    seed_top = PreferenceModel.from_seed().predict_ranking(features, rng)[0]
    favorite = "bingo" if seed_top != "bingo" else "dance"
    for index in range(100):
        _like_only(store, f"fan{index}", favorite, 1)
    learnt = PreferenceModel.train(store)
    assert learnt.training_size > PreferenceModel.from_seed().training_size
    assert learnt.predict_ranking(features, rng)[0] == favorite
    for index in range(100):
        store.erase(f"fan{index}")
    forgotten = PreferenceModel.train(store)
    assert forgotten.predict_ranking(features, rng)[0] == seed_top


def test_the_chooser_learns_a_users_taste_from_feedback(store: ProfileStore) -> None:
    persona = make_personas(1, seed=123)[0]
    store.get_or_create("ann", NOW)
    profile = store.update("ann", NOW, **persona.features)
    chooser = ActivityChooser(PreferenceModel.from_seed(), store)
    rng = random.Random(8)
    now = NOW
    picks: list[str] = []
    for _ in range(60):
        name = chooser.choose(profile, rng).activity
        picks.append(name)
        now += timedelta(minutes=5)
        profile = store.record_feedback("ann", name, persona.liking[name], now)
    truth = persona.ranking()
    assert tau(chooser.ranking(profile, rng), truth) >= 0.5
    late = Counter(picks[30:])
    # Favorites win as evidence grows; the least liked is hardly ever chosen late on.
    assert late[truth[0]] + late[truth[1]] >= 15
    assert late[truth[-1]] <= 3
    # (that it explores early on: test_preferences_evidence.py, over many users)


def test_cancellations_push_an_activity_down_and_exclude_is_respected(store: ProfileStore) -> None:
    store.get_or_create("ann", NOW)
    chooser = ActivityChooser(PreferenceModel.from_seed(), store)
    for _ in range(8):
        store.record_activity("ann", "quiz", NOW, NOW, "cancelled", "robot", True)
    profile = store.get("ann")
    rng = random.Random(2)
    picks = Counter(chooser.choose(profile, rng).activity for _ in range(200))
    assert picks["quiz"] < 5
    assert chooser.ranking(profile, rng)[-1] == "quiz"
    every_but_dance = [name for name in ENTERTAINMENT_ACTIVITIES if name != "dance"]
    assert {chooser.choose(profile, rng, exclude=every_but_dance).activity for _ in range(10)} == {
        "dance"
    }


def test_the_chooser_uses_the_profile_it_holds_when_the_store_is_gone(tmp_path: object) -> None:
    from pathlib import Path

    from sqlalchemy import text

    assert isinstance(tmp_path, Path)
    store = ProfileStore(f"sqlite:///{tmp_path / 'dms.db'}")
    store.get_or_create("ann", NOW)
    profile = store.update("ann", NOW, age=80, hobbies="cards")
    with store.engine.begin() as connection:
        connection.execute(text("DROP TABLE activity_scores"))
    chooser = ActivityChooser(PreferenceModel.from_seed(), store)
    assert chooser.choose(profile, random.Random(1)).activity in ENTERTAINMENT_ACTIVITIES
    store.close()
