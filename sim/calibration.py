"""Every input of the simulated study, with where its value comes from.

The study (:mod:`sim.study`) predicts the paper's Table 4 from these inputs and the
daemon's own decisions. An input's value comes from what the paper states about its
participants, protocol and content (``source`` names the passage), or is assumed
(``source`` starts with "assumed" and says why the value is plausible). No input is
set from the eight metrics of Table 4 but one: the robot's launch delay was first fitted
to the loading time, which makes that row an input. Two come from Table 4's failure
counts (the recognizer's error rate and the participants' silence), which makes those
two failure counts inputs, not predictions. ``tests/sim/test_study_calibration.py`` checks it.

``dms sim sensitivity`` moves each participant input (:data:`PARTICIPANT_INPUTS`) and the
robot's, content's and protocol's inputs (:data:`SETTING_INPUTS`) by ±50 % to show which
Table 4 metric follows which input.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Literal

Value = float | tuple[float, float]
"""A number, or a range (min, max) a value is drawn uniformly from."""
Kind = Literal["participant", "protocol", "robot", "content"]


@dataclass(frozen=True, slots=True)
class Input:
    """One input of the study: its value, unit and source."""

    value: Value
    unit: str
    kind: Kind
    source: str
    """The paper's passage it comes from, or "assumed: ..." with the reason."""


INPUTS: dict[str, Input] = {
    # who the participants are ("Experimental setup" of the first experiment)
    "age_min": Input(18, "years", "participant", "paper, Experiment 1 setup: aged 18-52"),
    "age_max": Input(52, "years", "participant", "paper, Experiment 1 setup: aged 18-52"),
    "women_share": Input(
        19 / 30, "share", "participant", "paper, Experiment 1 setup: 11 men, 19 women"
    ),
    # how they speak and answer
    "error_rate": Input(
        5 / 300,
        "per utterance",
        "participant",
        "paper, Table 4 failures: 5 speech recognition errors in 30 sessions (about 10 "
        "utterances a session: 5 in 300); the failure count is an input, not a prediction",
    ),
    "no_answer_rate": Input(
        0.0,
        "per question",
        "participant",
        "paper, Table 4 failures: user not answering 0; the failure count is an input",
    ),
    "answer_delay_s": Input(
        (2.0, 4.5), "s", "participant", "assumed: a spoken or tapped answer after a thought"
    ),
    "screen_rate": Input(
        0.8,
        "share",
        "participant",
        "assumed: they were told the activities are on the touch screen (Experiment 1 "
        "setup), so most answer there",
    ),
    "menu_delay_s": Input(
        (10.0, 40.0),
        "s",
        "participant",
        "assumed: a first-time user reading a touch-screen menu of eight activities",
    ),
    "rating_delay_s": Input(
        (3.0, 10.0), "s", "participant", "assumed: choosing a 1-5 rating on the screen"
    ),
    "arrive_after_s": Input(
        (3.0, 8.0), "s", "participant", "assumed: from sitting down to pressing Start"
    ),
    "ask_by_name_rate": Input(
        0.05,
        "per activity",
        "participant",
        "assumed: moderate proactivity (paper, Limitations: moderate for all users) "
        "rarely asks for an activity unprompted",
    ),
    # when they stop an activity (they were told how: Experiment 1 setup)
    "dislike_below": Input(
        0.25,
        "liking 0..1",
        "participant",
        "assumed: a liking that would be rated 1-2 of 5 (the rating is 1 + 4 x liking) "
        "is always stopped",
    ),
    "bored_below": Input(
        0.5,
        "liking 0..1",
        "participant",
        "assumed: under the middle of the rating scale an activity may be stopped, the "
        "more likely the less it is liked",
    ),
    "stop_after_s": Input(
        (45.0, 120.0), "s", "participant", "assumed: giving an activity a minute or two"
    ),
    "continue_rate": Input(
        0.1, "share", "participant", "assumed: changing one's mind when the robot asks"
    ),
    # the protocol
    "session_min": Input(30.0, "min", "protocol", "paper, Experiment 1 setup: 30 min sessions"),
    "survey_s": Input(
        180.0,
        "s",
        "protocol",
        "paper, Experiment 1 setup: the survey came after completing the activities and "
        "took around 3 min of the session time",
    ),
    "session_questions": Input(
        4,
        "questions",
        "protocol",
        "paper, Experiment 1 setup: 4-5 general questions after Start (the lower end)",
    ),
    "gap_s": Input(120.0, "s", "protocol", "assumed: time between two participants"),
    # the robot
    "launch_delay_s": Input(
        (2.0, 5.0),
        "s",
        "robot",
        "assumed: launching an activity's process on the robot's computer; the range was "
        "first fitted to Table 4's loading time (3.78 s), so that row is an input, not a "
        "prediction",
    ),
    # content the shipped activities do not fix themselves
    "media_s": Input(
        210.0,
        "s",
        "content",
        "assumed: a song or clip of three and a half minutes (the paper: dance plays a "
        "random song, multimedia plays music, photos or videos; no length given)",
    ),
}
"""The study's inputs by name."""

PARTICIPANT_INPUTS: tuple[str, ...] = (
    "error_rate",
    "answer_delay_s",
    "screen_rate",
    "menu_delay_s",
    "rating_delay_s",
    "arrive_after_s",
    "ask_by_name_rate",
    "dislike_below",
    "bored_below",
    "stop_after_s",
    "continue_rate",
)
"""The participants' habits ``dms sim sensitivity`` sweeps (ages and shares are who
they are, not a habit; a rate of 0 stays 0)."""

SETTING_INPUTS: tuple[str, ...] = ("launch_delay_s", "media_s", "survey_s", "gap_s")
"""The robot's, the content's and the protocol's inputs ``dms sim sensitivity`` sweeps too
(the protocol's general questions are a controller setting: ``session_questions``)."""

SHIPPED_CONTENT = (
    "The spoken activities' content (jokes, news, sayings, weather, quiz, bingo in "
    "activities/content) is the shipped one, sized by its authors to activities of about "
    "four minutes after the paper's mean execution time; the paper itself says only that "
    "the jokes activity tells three jokes. The execution time is therefore partly an input."
)


@dataclass(frozen=True, slots=True)
class Calibration:
    """A set of input values (the defaults, or some of them moved for a sensitivity run)."""

    values: tuple[tuple[str, Value], ...] = tuple((k, v.value) for k, v in INPUTS.items())

    def __getitem__(self, name: str) -> Value:
        return dict(self.values)[name]

    def number(self, name: str) -> float:
        value = self[name]
        if isinstance(value, tuple):
            raise TypeError(f"{name} is a range")
        return float(value)

    def optional(self, name: str) -> float | None:
        """A number these values may hold beside :data:`INPUTS` (a participants file's
        ``decline_menu_rate``), None when they do not."""
        value = dict(self.values).get(name)
        return None if value is None or isinstance(value, tuple) else float(value)

    def span(self, name: str) -> tuple[float, float]:
        value = self[name]
        if not isinstance(value, tuple):
            return (float(value), float(value))
        return (float(value[0]), float(value[1]))

    def scaled(self, name: str, factor: float) -> Calibration:
        """These inputs with ``name`` multiplied by ``factor`` (a probability or a liking
        stays in 0..1)."""
        value = self[name]
        if isinstance(value, tuple):
            moved: Value = (value[0] * factor, value[1] * factor)
        else:
            moved = value * factor
            if INPUTS[name].unit in ("share", "per utterance", "per question", "per activity"):
                moved = min(1.0, moved)
            if INPUTS[name].unit == "liking 0..1":
                moved = min(1.0, moved)
        values = tuple((k, moved if k == name else v) for k, v in self.values)
        return replace(self, values=values)


DEFAULT = Calibration()
