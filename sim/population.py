"""The study's participants: who sits in front of the robot, and their hidden tastes.

Two generators, selected with ``dms sim study --population``:

- ``paper`` (:func:`paper_participant`): adults like the paper's first experiment
  (ages, share of women, first time with a robot), drawn from the simulated world the
  robot's training data comes from (:func:`memory.seed_data.make_persona`): their
  hidden taste partly follows their features, as in ``memory/data/seed_rankings.csv``.
  The learner was fitted to that very structure, so Kendall's tau on this population
  measures the population as much as the learning;
- ``heldout`` (:func:`heldout_participant`): the same ages and shares, features drawn
  by a generator of their own and tastes from another structure (a mix of three
  archetypes, :data:`ARCHETYPES`, plus a taste of their own) that the features do not
  predict. What the robot gets right here it learnt from the visits.

Every habit (speech, pace, patience) is an input of :mod:`sim.calibration`, with its
source; nothing here is read by the decision logic, which learns about each participant
only by asking and watching (``tests/sim/test_study_guard.py`` checks it).
"""

from __future__ import annotations

import math
import random
from typing import Literal

from dms.kernel.activity_names import SHIPPED_ENTERTAINMENT
from memory.seed_data import EDUCATION, HOBBIES, OCCUPATIONS, SimulatedPersona, make_persona
from sim.calibration import DEFAULT, Calibration
from sim.persona import (
    INITIATIVE_ANSWER,
    Patience,
    Persona,
    Preferences,
    Proactivity,
    Span,
    SpeechHabits,
)

Population = Literal["paper", "personas", "heldout"]
ASK_BY_NAME_SCALE: dict[str, float] = {"low": 0.0, "moderate": 1.0, "high": 7.0}
"""By true proactivity, the calibrated chance of asking for a favourite by name
(``ask_by_name_rate``, a moderate participant's) multiplied by this."""
ARCHETYPES: dict[str, dict[str, float]] = {
    "lively": {"multimedia": 1.2, "dance": 1.4, "jokes": 0.8, "bingo": 0.3},
    "thoughtful": {"quiz": 1.3, "news": 1.1, "sayings": 0.6, "weather": 0.2},
    "homely": {"weather": 1.1, "bingo": 1.0, "sayings": 0.9, "news": 0.3},
}
"""The held-out population's taste structure: log-odds added by each archetype, mixed
by weights of the participant's own (not the training data's feature effects)."""
OWN_TASTE_SD = 0.8
"""The held-out participant's taste that no archetype explains (log-odds)."""


def _span(calibration: Calibration, name: str) -> Span:
    low, high = calibration.span(name)
    return Span(min=low, max=high)


def speech_habits(calibration: Calibration = DEFAULT) -> SpeechHabits:
    """How every participant speaks and answers (:mod:`sim.calibration`)."""
    return SpeechHabits(
        error_rate=calibration.number("error_rate"),
        answer_delay_s=_span(calibration, "answer_delay_s"),
        no_answer_rate=calibration.number("no_answer_rate"),
        screen_rate=calibration.number("screen_rate"),
        menu_delay_s=_span(calibration, "menu_delay_s"),
        rating_delay_s=_span(calibration, "rating_delay_s"),
    )


def patience(calibration: Calibration = DEFAULT) -> Patience:
    """When every participant stops an activity (:mod:`sim.calibration`)."""
    return Patience(
        dislike_below=calibration.number("dislike_below"),
        bored_below=calibration.number("bored_below"),
        stop_after_s=_span(calibration, "stop_after_s"),
        continue_rate=calibration.number("continue_rate"),
    )


def volunteer(rng: random.Random, woman: bool, calibration: Calibration) -> SimulatedPersona:
    """One adult of the paper's ages from the simulated world the robot's seed data comes
    from (:mod:`memory.seed_data`): features and a hidden taste that partly follows them."""
    low, high = calibration.number("age_min"), calibration.number("age_max")
    while True:
        person = make_persona(rng)
        age = int(person.features["age"])
        if low <= age <= high and (person.features["sex"] == "female") == woman:
            return person


def heldout_volunteer(
    rng: random.Random, woman: bool, calibration: Calibration
) -> SimulatedPersona:
    """One adult of the paper's ages whose taste is a mix of :data:`ARCHETYPES` and their
    own, drawn apart from their features (which the robot asks, but which say nothing of it)."""
    age = rng.randint(int(calibration.number("age_min")), int(calibration.number("age_max")))
    features: dict[str, str | int | bool] = {
        "age": age,
        "sex": "female" if woman else "male",
        "education": rng.choice(EDUCATION),
        "occupation": rng.choice(OCCUPATIONS),
        "hobbies": rng.choice(HOBBIES),
        "lives_alone": rng.random() < 0.3,
    }
    weights = [rng.gammavariate(0.7, 1.0) for _ in ARCHETYPES]
    total = sum(weights) or 1.0
    liking = {}
    for name in SHIPPED_ENTERTAINMENT:
        logit = -0.6 + rng.gauss(0.0, OWN_TASTE_SD)
        for weight, effects in zip(weights, ARCHETYPES.values(), strict=True):
            logit += 1.5 * weight / total * effects.get(name, 0.0)
        liking[name] = round(1 / (1 + math.exp(-logit)), 4)
    return SimulatedPersona(features, liking)


def paper_participant(
    index: int,
    rng: random.Random,
    level: Proactivity,
    calibration: Calibration = DEFAULT,
    heldout: bool = False,
) -> Persona:
    """Participant ``index`` (1-based): an adult of the paper's ages with hidden
    preferences of their own (``heldout``: from the held-out generator)."""
    name = f"p{index:02d}"
    woman = rng.random() < calibration.number("women_share")
    draw = heldout_volunteer if heldout else volunteer
    person = draw(rng, woman, calibration)
    features: dict[str, str | int | float | bool] = {
        "name": name.upper(),
        **{"gender" if key == "sex" else key: value for key, value in person.features.items()},
    }
    prefs = {activity: round(person.liking[activity], 3) for activity in SHIPPED_ENTERTAINMENT}
    ask = min(1.0, calibration.number("ask_by_name_rate") * ASK_BY_NAME_SCALE[level])
    return Persona(
        name=name,
        user_id=name,
        description="a volunteer of the paper's first experiment (adult, first time with a robot)",
        features=features,
        preferences=Preferences(**prefs),
        proactivity=level,
        ask_by_name_rate=ask,
        answers={"how often should i start": INITIATIVE_ANSWER[level]},
        decline_menu_rate=calibration.optional("decline_menu_rate"),
        speech=speech_habits(calibration),
        patience=patience(calibration),
        arrive_after_s=_span(calibration, "arrive_after_s"),
    )
