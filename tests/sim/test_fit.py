"""``dms sim fit``: simulated people with known habits, recorded as the daemon records
sessions, fitted back; the participants file it writes, and the studies that read it."""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Any

import pytest
import yaml
from typer.testing import CliRunner

from sim import fit
from sim.calibration import DEFAULT, Calibration
from sim.cli import app
from sim.errors import SpecError
from sim.study import run_study, study_settings

KNOWN: dict[str, Any] = {
    "answer_delay_s": (2.0, 4.0),
    "menu_delay_s": (12.0, 24.0),
    "rating_delay_s": (6.0, 10.0),
    "screen_rate": 1.0,
    "decline_menu_rate": 0.0,
}
"""People who tap every choice after these delays, choosing from every menu themselves
(none left to the robot: the menus observed are as many as the test was sized for)."""


@pytest.fixture(scope="module")
def tapped(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[dict[str, Any]]]:
    """A study of 14 such people, 20 minutes each, and its events table as a CSV file."""
    values = {**dict(DEFAULT.values), **KNOWN}
    result = run_study(
        14,
        20.0,
        seed=5,
        settings=study_settings(),
        calibration=Calibration(tuple(values.items())),
        record_events=True,
    )
    path = fit.write_events(tmp_path_factory.mktemp("fit") / "events.csv", result.events)
    return path, result.events


def test_the_delays_of_people_who_tap_are_recovered_within_their_intervals(
    tapped: tuple[Path, list[dict[str, Any]]],
) -> None:
    path, _events = tapped
    persons = fit.people(fit.read_table(path))
    assert len(persons) == 14
    fitted = {item.name: item for item in fit.fit(persons, bootstrap=200)}
    for name in ("answer_delay_s", "menu_delay_s", "rating_delay_s"):
        item = fitted[name]
        assert item.n >= 20, (name, item.n)
        assert all(item.covers(KNOWN[name])), (name, item.estimate, item.interval)
        width = KNOWN[name][1] - KNOWN[name][0]
        for low, high in item.interval:  # it says something: narrower than the range itself
            assert high - low < width, (name, item.interval)
    screen = fitted["screen_rate"]
    assert screen.estimate == 1.0 and screen.covers(1.0) == [True]
    assert screen.interval[0][0] < 1.0  # never seen otherwise, yet not certain


def test_the_table_read_back_from_csv_gives_what_the_rows_give(
    tapped: tuple[Path, list[dict[str, Any]]],
) -> None:
    path, events = tapped
    from_csv, from_rows = fit.people(fit.read_table(path)), fit.people(events)
    assert from_csv.keys() == from_rows.keys()
    for name, person in from_rows.items():
        assert from_csv[name].menu == person.menu
        assert dict(from_csv[name].counts) == dict(person.counts)


def _table(path: Path, rows: list[dict[str, Any]]) -> Path:
    defaults = {"session": "1", "user": "ann"}
    return fit.write_events(path, [{**defaults, **row} for row in rows])


def test_only_the_first_answer_to_an_offer_counts_and_each_rate_its_chances(
    tmp_path: Path,
) -> None:
    rows = [
        {"seq": 0, "t_s": 0.0, "event": "arrived"},
        {"seq": 1, "t_s": 0.0, "event": "offered", "offer": 1, "offer_kind": "question"},
        {"seq": 2, "t_s": 3.0, "event": "input", "offer": 1, "offer_kind": "question",
         "channel": "voice", "understood": False, "confidence": 0.2, "delay_s": 3.0},
        {"seq": 3, "t_s": 6.0, "event": "input", "offer": 1, "offer_kind": "question",
         "channel": "voice", "understood": True, "confidence": 0.9, "delay_s": 6.0},
        {"seq": 4, "t_s": 7.0, "event": "offered", "offer": 2, "offer_kind": "menu"},
        {"seq": 5, "t_s": 27.0, "event": "input", "offer": 2, "offer_kind": "menu",
         "channel": "screen", "value": "you choose", "delay_s": 20.0},
        {"seq": 6, "t_s": 28.0, "event": "started", "activity": "quiz", "by": "robot"},
        {"seq": 7, "t_s": 88.0, "event": "input", "channel": "touch", "value": "right_shoulder"},
        {"seq": 8, "t_s": 88.0, "event": "offered", "offer": 3, "offer_kind": "confirm"},
        {"seq": 9, "t_s": 91.0, "event": "input", "offer": 3, "offer_kind": "confirm",
         "channel": "screen", "value": "continue", "delay_s": 3.0},
        {"seq": 10, "t_s": 200.0, "event": "completed", "activity": "quiz"},
        {"seq": 11, "t_s": 200.0, "event": "offered", "offer": 4, "offer_kind": "rating"},
        {"seq": 12, "t_s": 230.0, "event": "unanswered", "offer": 4, "offer_kind": "rating"},
        {"seq": 13, "t_s": 240.0, "event": "left"},
    ]  # fmt: skip
    (ann,) = fit.people(fit.read_table(_table(tmp_path / "events.csv", rows))).values()
    assert ann.answer == [3.0, 3.0] and ann.menu == [20.0] and ann.rating == []
    assert ann.stop_after == [60.0] and ann.session_min == [4.0]
    assert dict(ann.counts) == {
        "error_rate": [1, 2],
        "no_answer_rate": [1, 3],
        "screen_rate": [2, 2],
        "continue_rate": [1, 1],
        "decline_menu_rate": [1, 1],
    }


def test_a_participants_file_is_written_read_back_and_drawn_from(
    tapped: tuple[Path, list[dict[str, Any]]], tmp_path: Path
) -> None:
    path, _events = tapped
    out = tmp_path / "participants.yaml"
    runner = CliRunner()
    done = runner.invoke(app, ["fit", str(path), "--out", str(out), "--bootstrap", "60"])
    assert done.exit_code == 0, done.output
    assert "menu_delay_s" in done.output and "bootstrap over people" in done.output
    document = yaml.safe_load(out.read_text())
    assert document["format"] == fit.FORMAT and document["people"] == 14
    menu = document["inputs"]["menu_delay_s"]
    assert set(menu) == {"unit", "n", "source", "estimate", "interval"}
    assert menu["source"].startswith("fitted by dms sim fit from ")
    calibration, used = fit.load_participants(out)
    assert calibration.span("menu_delay_s") == tuple(menu["estimate"])
    assert "session_min" not in used and "menu_delay_s" in used
    assert calibration.number("session_min") == DEFAULT.number("session_min")
    studied = runner.invoke(
        app, ["study", "--sessions", "1", "--minutes", "3", "--participants", str(out), "--json"]
    )
    assert studied.exit_code == 0, studied.output


@pytest.mark.parametrize(
    ("text", "named"),
    [
        ("format: something-else\n", "not a participants file"),
        ("{{{", "not YAML"),
        (f"format: {fit.FORMAT}\ninputs: {{colour: {{estimate: 1}}}}\n", "unknown input 'colour'"),
        (f"format: {fit.FORMAT}\ninputs: {{error_rate: {{estimate: 2}}}}\n", "at most 1"),
        (
            f"format: {fit.FORMAT}\ninputs: {{menu_delay_s: {{estimate: [9, 3]}}}}\n",
            "max is below min",
        ),
        (f"format: {fit.FORMAT}\ninputs: {{menu_delay_s: {{estimate: 4}}}}\n", "[min, max]"),
    ],
)
def test_a_bad_participants_file_is_refused_in_one_line(
    tmp_path: Path, text: str, named: str
) -> None:
    path = tmp_path / "p.yaml"
    path.write_text(text)
    with pytest.raises(SpecError, match=named.replace("[", r"\[").replace("]", r"\]")) as error:
        fit.load_participants(path)
    assert "\n" not in str(error.value)


def test_fit_refuses_a_table_that_is_not_an_events_table(tmp_path: Path) -> None:
    path = tmp_path / "sessions.csv"
    with path.open("w", newline="") as handle:
        csv.writer(handle).writerows([["session", "user", "started"], ["1", "ann", "x"]])
    done = CliRunner().invoke(app, ["fit", str(path), "--out", str(tmp_path / "p.yaml")])
    assert done.exit_code != 0
    assert isinstance(done.exception, SpecError) and "not an events table" in str(done.exception)
    assert not (tmp_path / "p.yaml").exists()
