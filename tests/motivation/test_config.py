"""The ``[motivation]`` table: defaults, partial overrides, custom drives, one-line errors."""

from __future__ import annotations

import tomllib
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from motivation import (
    DEFAULT_DRIVES,
    MotivationConfig,
    MotivationConfigError,
    MotivationModel,
    load_config,
    simulate,
)

START = datetime(2026, 11, 23, 8, 0, tzinfo=UTC)


def test_the_defaults() -> None:
    config = load_config({})
    assert config == load_config(None) == MotivationConfig()
    assert list(config.active_drives) == ["rest", "social", "play"]
    assert {name: d.behavior for name, d in config.drives.items()} == {
        "rest": "sleep",
        "social": "presentation",
        "play": "dance",
    }
    assert config.idle_behavior == "wait"
    assert config.hysteresis == 10.0
    assert config.drives["rest"].release == 15.0


def test_a_partial_override_keeps_the_other_defaults() -> None:
    config = load_config({"drives": {"rest": {"threshold": 70}}, "hysteresis": 5})
    rest = config.drives["rest"]
    assert rest.threshold == 70
    for name, value in DEFAULT_DRIVES["rest"].items():
        if name != "threshold":
            assert getattr(rest, name) == value, name
    assert config.drives["social"] == MotivationConfig().drives["social"]
    assert config.hysteresis == 5


def test_enabled_false_removes_a_drive() -> None:
    config = load_config({"drives": {"play": {"enabled": False}}})
    assert list(config.active_drives) == ["rest", "social"]
    model = MotivationModel(config)
    assert model.names == ("rest", "social")
    state = model.initial_state(START)
    assert len(state.drives) == 2
    drives = model.snapshot(state)["drives"]
    assert isinstance(drives, dict) and set(drives) == {"rest", "social"}


def test_a_custom_fourth_drive_works() -> None:
    config = load_config(
        {
            "drives": {
                "curiosity": {
                    "rate_per_hour": 20.0,
                    "threshold": 50.0,
                    "satiation": 10.0,
                    "stimulus_weight": 5.0,
                    "stimuli": ["user"],
                    "behavior": "news",
                    "satisfied_by": {"news": 2.0},
                    "initial": 45.0,
                }
            }
        }
    )
    model = MotivationModel(config)
    assert model.names == ("rest", "social", "play", "curiosity")
    state = model.initial_state(START)
    run = simulate(model, state, START, 4 * 3600, model.no_stimuli(), follow=True, every=120)
    curious = model.names.index("curiosity")
    assert curious in run.dominant.tolist()
    names = np.array([*model.table.behaviors, "wait"])[run.dominant]
    assert "news" in names.tolist()
    # while the news runs, curiosity falls
    reading = np.flatnonzero(names == "news")
    assert run.drives[reading[-1], curious] < run.drives[reading[0], curious]


@pytest.mark.parametrize(
    ("table", "expected"),
    [
        (
            {"drives": {"rest": {"threshold": 150}}},
            "motivation.drives.rest.threshold: must be in [0, 100] (got 150)",
        ),
        (
            {"drives": {"rest": {"peak_hour": 24}}},
            "motivation.drives.rest.peak_hour: must be in [0, 24) (got 24)",
        ),
        ({"hysteresis": -1}, "motivation.hysteresis: must be in [0, 100] (got -1)"),
        (
            {"drives": {"social": {"amplitude": "much"}}},
            "motivation.drives.social.amplitude: must be a number in [0, 1] (got 'much')",
        ),
        (
            {"stimuli": {"dark_lux": 0}},
            "motivation.stimuli.dark_lux: must be in (0, 100000] (got 0)",
        ),
        (
            {"drives": {"rest": {"satiation": 70}}},
            "motivation.drives.rest.satiation: must not exceed the threshold (60) (got 70)",
        ),
        (
            {"drives": {"rest": {"colour": "red"}}},
            "motivation.drives.rest.colour: Extra inputs are not permitted (got 'red')",
        ),
        ({"mood": 3}, "motivation.mood: Extra inputs are not permitted (got 3)"),
        (
            {"drives": {"play": {"satisfied_by": {"dance": 500}}}},
            "motivation.drives.play.satisfied_by: dance: points per minute must be in [0, 100]",
        ),
        (
            {"stimuli": {"quiet_db": 70}},
            "motivation.stimuli: loud_db (60.0) must be above quiet_db (70.0)",
        ),
        (
            {"drives": {name: {"enabled": False} for name in ("rest", "social", "play")}},
            "motivation: drives: at least one drive must be enabled",
        ),
    ],
)
def test_a_wrong_value_is_one_line_naming_the_field_and_range(
    table: dict[str, Any], expected: str
) -> None:
    with pytest.raises(MotivationConfigError) as error:
        load_config(table)
    message = str(error.value)
    assert message.startswith(expected)
    assert "\n" not in message


@pytest.mark.parametrize(
    ("table", "field"),
    [
        ({"drives": {"rest": {"behavior": "fly"}}}, "motivation.drives.rest.behavior"),
        ({"idle_behavior": "nap"}, "motivation.idle_behavior"),
        ({"drives": {"play": {"satisfied_by": {"juggle": 1}}}}, "motivation.drives.play"),
        ({"drives": {"play": {"dormant_during": ["nap"]}}}, "motivation.drives.play"),
    ],
)
def test_an_unknown_behavior_is_refused(table: dict[str, Any], field: str) -> None:
    with pytest.raises(MotivationConfigError, match="unknown behavior") as error:
        load_config(table)
    assert str(error.value).startswith(field)
    assert "sleep" in str(error.value)  # the line lists what is allowed


def test_a_custom_drive_needs_its_rate_threshold_and_behavior() -> None:
    with pytest.raises(MotivationConfigError) as error:
        load_config({"drives": {"hunger": {"rate_per_hour": 1.0}}})
    assert str(error.value) == "motivation.drives.hunger.threshold: Field required; and 1 more"


def test_an_unknown_stimulus_source_is_refused() -> None:
    with pytest.raises(MotivationConfigError, match=r"motivation\.drives\.rest\.stimuli\.0"):
        load_config({"drives": {"rest": {"stimuli": ["smell"]}}})


def test_the_documented_example_loads() -> None:
    """docs/motivation.md's TOML example is valid and does what its comments say."""
    text = (Path(__file__).resolve().parents[2] / "docs" / "motivation.md").read_text("utf-8")
    example = text.split("```toml\n", 1)[1].split("```", 1)[0]
    config = load_config(tomllib.loads(example)["motivation"])
    assert list(config.active_drives) == ["rest", "social", "curiosity"]
    assert config.drives["rest"].threshold == 65 and config.drives["rest"].release == 20
    assert config.drives["rest"].rate_per_hour == DEFAULT_DRIVES["rest"]["rate_per_hour"]
    assert config.drives["curiosity"].behavior == "news"
