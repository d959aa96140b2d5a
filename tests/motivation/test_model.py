"""The shipped model on the virtual clock: days and nights, users, the room, caresses.

No test reads the system clock: every run starts at a fixed instant and moves by
``step``, ``advance`` or ``simulate``.
"""

from __future__ import annotations

from datetime import UTC, datetime, timedelta
from zoneinfo import ZoneInfo

import numpy as np
import pytest

from motivation import (
    NO_DOMINANT,
    MotivationModel,
    MotivationState,
    Percepts,
    Stimuli,
    advance,
    load_config,
    simulate,
)

NOON = datetime(2026, 11, 23, 12, 0, tzinfo=UTC)  # a Monday, winter time in Madrid
MINUTE_TICKS = 120  # samples every minute at 2 Hz


def behaviors_over(model: MotivationModel, start: datetime, hours: float) -> tuple[np.ndarray, ...]:
    """Local hour of day and behavior at each minute of an idle run following the motivation."""
    run = simulate(
        model,
        model.initial_state(start),
        start,
        hours * 3600,
        model.no_stimuli(),
        follow=True,
        every=MINUTE_TICKS,
    )
    names = np.array([*model.table.behaviors, model.config.idle_behavior])
    local = start.astimezone(model.zone)
    hours_since_midnight = local.hour + local.minute / 60 + run.seconds / 3600
    return hours_since_midnight, hours_since_midnight % 24, names[run.dominant]


@pytest.mark.parametrize("zone", ["UTC", "Europe/Madrid"])
def test_an_idle_robot_sleeps_at_night_over_two_days(zone: str) -> None:
    model = MotivationModel(zone=ZoneInfo(zone))
    start = datetime(2026, 11, 23, 12, 0, tzinfo=ZoneInfo(zone))  # local noon
    since, hour, doing = behaviors_over(model, start, 48)
    asleep = doing == "sleep"
    for night in (1, 2):  # 00:00-06:00 of the next two days
        small_hours = (since >= 24 * night) & (since < 24 * night + 6)
        assert asleep[small_hours].mean() > 0.9
    night_time = (hour >= 21) | (hour < 9)
    assert asleep[night_time].sum() / asleep.sum() > 0.9
    daytime = (hour >= 11) & (hour < 20)
    assert asleep[daytime].mean() < 0.05
    # by day it is bored now and then (dance) and lonely now and then (calls for attention)
    assert {"dance", "presentation", "wait"} <= set(doing[daytime].tolist())


def test_an_idle_robot_does_not_flicker() -> None:
    model = MotivationModel()
    run = simulate(
        model, model.initial_state(NOON), NOON, 48 * 3600, model.no_stimuli(), follow=True
    )
    changes = np.flatnonzero(run.dominant[1:] != run.dominant[:-1])
    shortest = np.diff(changes).min() * 0.5
    assert shortest >= 120.0  # every behavior it picks runs at least two minutes
    assert run.switches == len(changes) < 60


def test_a_user_present_and_engaged_calms_loneliness() -> None:
    model = MotivationModel()
    social = model.names.index("social")
    state = MotivationState(np.array([30.0, 80.0, 30.0]), np.zeros(3))
    engaged = model.stimuli(Percepts(user_present=True, engagement=1.0))
    assert engaged.levels[social] == 1.0
    after = advance(model, state, 1800, engaged, "quiz", NOON)
    assert after.drives[social] < state.drives[social] - 20  # 1 point a minute off
    alone = advance(model, state, 1800, model.no_stimuli(), "quiz", NOON)
    assert alone.drives[social] > state.drives[social]
    # the stimulus itself raises the motivation to seek company: M = D + alpha * w
    motivations = model.motivations(state.drives, engaged.levels)
    assert motivations[social] == pytest.approx(80.0 + 20.0)


def test_an_absent_or_unknown_user_does_not_count() -> None:
    model = MotivationModel()
    social = model.names.index("social")
    for percepts in (
        Percepts(user_present=False, engagement=1.0),
        Percepts(user_present=None, engagement=1.0),
    ):
        inputs = model.stimuli(percepts)
        assert inputs.levels[social] == 0.0 and inputs.relief[social] == 0.0
    unknown_engagement = model.stimuli(Percepts(user_present=True))
    assert unknown_engagement.levels[social] == model.config.stimuli.default_engagement


@pytest.mark.parametrize(
    ("env", "level"),
    [
        ({"light_lux": 0.0, "noise_db": 20.0}, 1.0),  # dark and quiet
        ({"light_lux": 0.0}, 1.0),  # dark, noise unknown
        ({"noise_db": 30.0}, 1.0),  # quiet, light unknown
        ({"light_lux": 150.0, "noise_db": 80.0}, 0.5),  # half dark, loud
        ({"light_lux": 1000.0, "noise_db": 45.0}, 0.5),  # bright, half quiet
        ({"light_lux": 1000.0, "noise_db": 70.0}, 0.0),  # bright and loud
        ({}, 0.0),
    ],
)
def test_darkness_and_quiet_excite_rest(env: dict[str, float], level: float) -> None:
    model = MotivationModel()
    rest = model.names.index("rest")
    inputs = model.stimuli(Percepts(env=env))
    assert inputs.levels[rest] == pytest.approx(level)
    assert np.all(np.delete(inputs.levels, rest) == 0.0)
    tired = np.array([70.0, 20.0, 20.0])
    motivations = model.motivations(tired, inputs.levels)
    assert motivations[rest] == pytest.approx(70.0 + 15.0 * level)


def test_a_dark_room_makes_rest_take_over_sooner() -> None:
    """At 65 both rest and social are active; the dark adds 15 to rest, which then leads."""
    model = MotivationModel()
    drives = np.array([65.0, 70.0, 20.0])
    dark = model.stimuli(Percepts(env={"light_lux": 0.0, "noise_db": 20.0}))
    lit = model.stimuli(Percepts(env={"light_lux": 800.0, "noise_db": 70.0}))
    assert model.names[model.next_dominant(NO_DOMINANT, drives, lit.levels)] == "social"
    assert model.names[model.next_dominant(NO_DOMINANT, drives, dark.levels)] == "rest"


@pytest.mark.parametrize(
    "percepts",
    [
        Percepts(),
        Percepts(env=None, touches=()),
        Percepts(env={"light_lux": None, "noise_db": None, "music": None}),
        Percepts(env={"light_lux": "dark", "noise_db": float("nan"), "music": "loud"}),
        Percepts(env={"light_lux": True, "noise_db": float("inf")}),
        Percepts(env={"temperature": 21.0}),
        Percepts(touches=(("head", "tap"), ("left_hand", "hit"))),
    ],
)
def test_a_missing_input_contributes_nothing(percepts: Percepts) -> None:
    model = MotivationModel()
    inputs = model.stimuli(percepts)
    assert np.all(inputs.levels == 0.0)
    assert np.all(inputs.relief == 0.0)
    assert np.all(inputs.instant == 0.0)
    state = MotivationState(np.array([50.0, 50.0, 50.0]), np.zeros(3))
    with_nothing = advance(model, state, 3600, inputs, None, NOON)
    no_stimuli = advance(model, state, 3600, model.no_stimuli(), None, NOON)
    np.testing.assert_array_equal(with_nothing.drives, no_stimuli.drives)


def test_music_excites_play() -> None:
    model = MotivationModel()
    play = model.names.index("play")
    for env in ({"music": True}, {"music": 1}, {"music": 0.7}):
        assert model.stimuli(Percepts(env=env)).levels[play] == 1.0
    for env in ({"music": False}, {"music": 0}):
        assert model.stimuli(Percepts(env=env)).levels[play] == 0.0


def test_caresses_excite_social_and_take_touch_relief_off() -> None:
    model = MotivationModel()
    social = model.names.index("social")
    touches = (("head", "caress"), ("belly", "tap"), ("head", "caress"))
    inputs = model.stimuli(Percepts(touches=touches))
    assert inputs.levels[social] == 1.0
    relief = model.config.drives["social"].touch_relief
    assert inputs.instant[social] == 2 * relief
    assert np.all(np.delete(inputs.instant, social) == 0.0)
    state = MotivationState(np.array([30.0, 70.0, 30.0]), np.zeros(3))
    after = model.step(state, 0.5, inputs, None, NOON)
    growth = model.step(state, 0.5, model.no_stimuli(), None, NOON)
    assert after.drives[social] == pytest.approx(growth.drives[social] - 2 * relief)
    # the relief counts once, not once per tick, in a long run too
    run = advance(model, state, 60.0, inputs, None, NOON)
    alone = advance(model, state, 60.0, model.no_stimuli(), None, NOON)
    assert run.drives[social] == pytest.approx(alone.drives[social] - 2 * relief)
    # and never below 0
    calm = MotivationState(np.array([30.0, 1.0, 30.0]), np.zeros(3))
    assert model.step(calm, 0.0, inputs, None, NOON).drives[social] == 0.0


def test_behaviors_satisfy_their_drives_and_dormant_drives_rest() -> None:
    model = MotivationModel()
    rest, social, play = (model.names.index(n) for n in ("rest", "social", "play"))
    state = MotivationState(np.array([80.0, 50.0, 50.0]), np.zeros(3))
    asleep = advance(model, state, 3600, model.no_stimuli(), "sleep", NOON)
    assert asleep.drives[rest] < state.drives[rest]
    # asleep, the robot gets neither lonely nor bored
    assert asleep.drives[social] == state.drives[social]
    assert asleep.drives[play] == state.drives[play]
    dancing = advance(model, state, 3600, model.no_stimuli(), "dance", NOON)
    assert dancing.drives[play] < state.drives[play] - 40
    assert dancing.drives[social] > state.drives[social]


def test_dominant_motivation_behavior_and_satiation() -> None:
    model = MotivationModel()
    levels = np.zeros(3)
    assert model.next_dominant(NO_DOMINANT, np.array([20.0, 20.0, 20.0]), levels) == NO_DOMINANT
    assert model.behavior(MotivationState(np.zeros(3), levels)) == "wait"
    rest = model.next_dominant(NO_DOMINANT, np.array([61.0, 20.0, 20.0]), levels)
    assert model.names[rest] == "rest"
    assert model.behavior(MotivationState(np.zeros(3), levels, rest)) == "sleep"
    # held below its threshold until it falls under its satiation level (15 for rest)
    assert model.next_dominant(rest, np.array([16.0, 20.0, 20.0]), levels) == rest
    motivations = model.motivations(np.array([16.0, 20.0, 20.0]), levels, rest)
    assert motivations.tolist() == [16.0, 0.0, 0.0]
    assert model.next_dominant(rest, np.array([14.0, 20.0, 20.0]), levels) == NO_DOMINANT
    # another drive must exceed it by the margin (10) to take over
    assert model.next_dominant(rest, np.array([61.0, 70.0, 20.0]), levels) == rest
    assert model.names[model.next_dominant(rest, np.array([61.0, 71.5, 20.0]), levels)] == (
        "social"
    )


def test_wellbeing_and_snapshot() -> None:
    model = MotivationModel(load_config({"drives": {"rest": {"wellbeing_weight": 2.0}}}))
    drives = np.array([40.0, 10.0, 70.0])
    assert model.wellbeing(drives) == pytest.approx(100 - (2 * 40 + 10 + 70) / 4)
    assert model.wellbeing(np.full(3, 100.0)) == 0.0
    assert model.wellbeing(np.zeros(3)) == 100.0
    state = MotivationState(drives, np.array([0.0, 0.0, 1.0]), model.names.index("play"))
    snapshot = model.snapshot(state)
    assert snapshot == {
        "dominant": "play",
        "drives": {"rest": 40.0, "social": 10.0, "play": 70.0},
        "motivations": {"rest": 0.0, "social": 0.0, "play": 85.0},
        "wellbeing": 60.0,
    }


def test_a_local_time_zone_shifts_the_rhythm() -> None:
    """Rest grows fastest at 02:00 local: 02:00 UTC in UTC, 01:00 UTC in Madrid in winter."""

    def fastest_hour(model: MotivationModel) -> float:
        day = datetime(2026, 11, 23, tzinfo=UTC)
        state = MotivationState(np.array([50.0, 50.0, 50.0]), np.zeros(3))
        growth = []
        for minute in range(0, 24 * 60, 5):
            now = day + timedelta(minutes=minute)
            after = model.step(state, 60.0, model.no_stimuli(), None, now)
            growth.append(after.drives[0] - state.drives[0])
        return int(np.argmax(growth)) * 5 / 60

    assert fastest_hour(MotivationModel()) == pytest.approx(2.0, abs=0.1)
    assert fastest_hour(MotivationModel(zone=ZoneInfo("Europe/Madrid"))) == pytest.approx(
        1.0, abs=0.1
    )


def test_a_step_backwards_is_refused() -> None:
    model = MotivationModel()
    with pytest.raises(ValueError, match="dt must not be negative"):
        model.step(model.initial_state(NOON), -1.0, model.no_stimuli(), None, NOON)
    with pytest.raises(ValueError, match="tick_s must be positive"):
        simulate(model, model.initial_state(NOON), NOON, 10.0, model.no_stimuli(), tick_s=0)


def test_the_initial_state() -> None:
    model = MotivationModel(load_config({"drives": {"rest": {"initial": 75.0}}}))
    state = model.initial_state(NOON)
    assert state.drives.tolist() == [75.0, 20.0, 20.0]
    assert model.dominant(state) == "rest"
    assert isinstance(model.no_stimuli(), Stimuli)
