"""The study's participants: a population like the seed's first experiment.

The seed's usability study ("Experimental setup") had 30 Spanish adults aged 18-52
(11 men, 19 women) who had never met a social robot, told how to cancel an activity and
that activities are on the touch screen, with moderate proactivity set for everyone.
:func:`paper_participant` draws one such participant as a :class:`~sim.persona.Persona`.
Everything here is an *input* to the simulation (who sits in front of the robot and how
they behave); nothing in it is read by the decision logic, which learns about each
participant only by asking and watching (``tests/sim/test_study_guard.py`` checks it).

Why each habit has the value it has:

- speech: young adults speaking clearly in a quiet room; the seed counted 5
  misrecognitions in 30 sessions, so the recognizer errs on about 1.5 % of utterances;
  nobody failed to answer (0 in the seed): ``no_answer_rate`` 0;
- they prefer the touch screen when it shows choices (they were told activities are on
  the screen);
- ``menu_delay_s``: first-time users looking through the activity menus (the seed's
  Fig. 5) before tapping one, and ``rating_delay_s``: thinking of a 1-5 rating. These
  two spans are set so that the time between activities comes out as the seed's
  (43.1 s): a calibration of the users' pace, documented as such in docs/simulation.md;
- they stop an activity they clearly dislike (liked under 0.3) after a minute or two of
  giving it a chance, and one they find so-so the more often the less they like it
  (up to 0.65): the seed counted 0.53 cancels a session;
- each participant is drawn from the simulated world the robot's seed data comes from
  (:func:`memory.seed_data.make_persona`, kept to the seed's ages and share of women):
  their features (age, gender, education, occupation, hobbies, living alone) and a
  hidden taste that partly follows them and partly is their own, as the seed's
  preference learning assumes of people ("a dataset containing the characteristics and
  preferences of similar users"). No two are alike, so the robot has something to learn;
- ``proactivity`` is the participant's true one: low leaves most menus to the robot
  ("you choose"), high picks and also asks for favourites by name.
"""

from __future__ import annotations

import random

from dms.kernel.activity_names import ENTERTAINMENT_ACTIVITIES
from memory.seed_data import SimulatedPersona, make_persona
from sim.persona import Patience, Persona, Preferences, Proactivity, Span, SpeechHabits

AGES = (18, 52)
WOMEN_SHARE = 19 / 30
ASK_BY_NAME_RATE: dict[str, float] = {"low": 0.0, "moderate": 0.05, "high": 0.35}
"""After an activity, the chance of asking for a favourite by name, by true proactivity."""
INITIATIVE_ANSWER: dict[str, str] = {"low": "high", "moderate": "moderate", "high": "low"}
"""The answer to "how often should I start a conversation?": a user who lets the robot
lead wants it to start often."""

SPEECH = SpeechHabits(
    error_rate=0.015,
    answer_delay_s=Span(min=2.0, max=4.5),
    no_answer_rate=0.0,
    screen_rate=0.8,
    menu_delay_s=Span(min=60.0, max=90.0),
    rating_delay_s=Span(min=8.0, max=14.0),
)
PATIENCE = Patience(
    dislike_below=0.3, bored_below=0.65, stop_after_s=Span(min=45.0, max=120.0), continue_rate=0.1
)


def volunteer(rng: random.Random, woman: bool) -> SimulatedPersona:
    """One adult of the seed's ages from the simulated world the robot's seed data comes
    from (:mod:`memory.seed_data`): features and a hidden taste that partly follows them."""
    while True:
        person = make_persona(rng)
        age = int(person.features["age"])
        if AGES[0] <= age <= AGES[1] and (person.features["sex"] == "female") == woman:
            return person


def paper_participant(index: int, rng: random.Random, level: Proactivity) -> Persona:
    """Participant ``index`` (1-based): an adult of 18-52 with hidden preferences of their own."""
    name = f"p{index:02d}"
    person = volunteer(rng, rng.random() < WOMEN_SHARE)
    features: dict[str, str | int | float | bool] = {
        "name": name.upper(),
        **{"gender" if key == "sex" else key: value for key, value in person.features.items()},
    }
    prefs = {activity: round(person.liking[activity], 3) for activity in ENTERTAINMENT_ACTIVITIES}
    return Persona(
        name=name,
        user_id=name,
        description="a volunteer of the seed's first experiment (adult, first time with a robot)",
        features=features,
        preferences=Preferences(**prefs),
        proactivity=level,
        ask_by_name_rate=ASK_BY_NAME_RATE[level],
        answers={"how often should i start": INITIATIVE_ANSWER[level]},
        speech=SPEECH,
        patience=PATIENCE,
        arrive_after_s=Span(min=3.0, max=8.0),
    )
