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
- they stop an activity they clearly dislike after a minute or two of giving it a chance
  (the seed: 0.53 cancels a session);
- the hidden preferences are drawn per participant (no two alike), so the robot has
  something to learn;
- ``proactivity`` is the participant's true one: low leaves most menus to the robot
  ("you choose"), high picks and also asks for favourites by name.
"""

from __future__ import annotations

import random

from dms.kernel.activity_names import ENTERTAINMENT_ACTIVITIES
from sim.persona import Patience, Persona, Preferences, Proactivity, Span, SpeechHabits

AGES = (18, 52)
WOMEN_SHARE = 19 / 30
OCCUPATIONS = (
    "student",
    "engineer",
    "teacher",
    "nurse",
    "researcher",
    "administrative",
    "designer",
)
HOBBIES = ("films", "music", "reading", "sports", "travel", "cooking", "video games")
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
PATIENCE = Patience(dislike_below=0.3, stop_after_s=Span(min=45.0, max=120.0), continue_rate=0.1)


def paper_participant(index: int, rng: random.Random, level: Proactivity) -> Persona:
    """Participant ``index`` (1-based): an adult of 18-52 with hidden preferences of their own."""
    name = f"p{index:02d}"
    women = rng.random() < WOMEN_SHARE
    prefs = {activity: round(rng.betavariate(2.0, 2.0), 3) for activity in ENTERTAINMENT_ACTIVITIES}
    features: dict[str, str | int | float | bool] = {
        "name": name.upper(),
        "age": rng.randint(*AGES),
        "gender": "female" if women else "male",
        "occupation": rng.choice(OCCUPATIONS),
        "education": "university" if rng.random() < 0.7 else "secondary",
        "hobbies": rng.choice(HOBBIES),
        "lives_alone": rng.random() < 0.3,
    }
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
