"""``dms sim sensitivity``: an input moves the metric it drives."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from dms.cli import main
from sim.sensitivity import sweep


def test_patience_moves_cancels_and_menu_time_moves_the_change_time() -> None:
    result = sweep(["bored_below", "menu_delay_s"], [0], sessions=4, minutes=12.0)
    # Stopping activities up to a higher liking cancels more of them.
    assert result.effect("bored_below", "high", "cancels_per_session") > result.effect(
        "bored_below", "low", "cancels_per_session"
    )
    # Slower menus lengthen the time between activities.
    assert result.effect("menu_delay_s", "high", "change_time_s") > 0.0
    assert result.effect("menu_delay_s", "low", "change_time_s") < 0.0


def test_the_command_writes_a_csv_and_a_tornado_chart(tmp_path: Path) -> None:
    args = ["sim", "sensitivity", "--sessions", "2", "--minutes", "6", "--seeds", "0"]
    args += ["--only", "screen_rate", "--out", str(tmp_path)]
    assert main(args) == 0
    rows = (tmp_path / "sensitivity.csv").read_text().splitlines()
    assert rows[0].startswith("input,direction")
    assert len(rows) > 2
    assert (tmp_path / "sensitivity.png").stat().st_size > 1000


def test_the_robots_and_the_controllers_inputs_move_their_rows_above_the_noise() -> None:
    inputs = ["launch_delay_s", "controller.session_questions"]
    result = sweep(inputs, [0, 1, 2], sessions=4, minutes=8.0)
    assert set(result.noise) == set(result.baseline)  # a floor per metric
    load = "activity_load_time_s"
    assert result.effect("launch_delay_s", "high", load) > result.noise[load] > 0.0
    assert result.effect("launch_delay_s", "low", load) < 0.0
    assert result.driver(load) == "launch_delay_s"
    asked = "questions_per_session"  # 4 questions moved to 2 and 6
    assert result.effect("controller.session_questions", "low", asked) == -2.0
    assert result.effect("controller.session_questions", "high", asked) == 2.0
    assert result.to_json()["noise_floor"][load] == round(result.noise[load], 4)


def test_an_unknown_input_is_refused_naming_the_known_ones(tmp_path: Path) -> None:
    args = ["sim", "sensitivity", "--only", "menu_delay", "--out", str(tmp_path)]
    assert main(args) == 2


def test_the_sweep_runs_with_a_baseline_chooser_on_either_population(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    liking = {}
    for chooser in ("oracle", "least_liked"):
        args = ["sim", "sensitivity", "--sessions", "3", "--minutes", "8", "--seeds", "0,1"]
        args += ["--only", "screen_rate", "--out", str(tmp_path / chooser), "--json"]
        args += ["--chooser", chooser, "--population", "heldout", "--jobs", "2"]
        assert main(args) == 0
        liking[chooser] = json.loads(capsys.readouterr().out)["baseline"]["robot_choice_liking"]
    # the participants' best and worst picks: the sweep ran each chooser, not the default's
    assert liking["oracle"] > liking["least_liked"] + 0.3, liking
