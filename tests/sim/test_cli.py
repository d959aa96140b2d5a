"""The sim commands through the ``dms`` entry point: exit codes, output, JSON keys."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from dms.cli import main
from sim.scenario import SCENARIO_DIR

STUDY_KEYS = {
    "sessions",
    "questions_per_session",
    "activities_per_session",
    "activity_load_time_s",
    "activity_time_s",
    "change_time_s",
    "robot_decisions_per_session",
    "user_selections_per_session",
    "cancels_per_session",
    "failures",
    "wall_s",
}
FAILURE_KEYS = {"activity_not_loaded", "speech_recognition_errors", "user_not_answering", "other"}
LONGTERM_KEYS = {
    "days",
    "ticks",
    "wall_s",
    "drives_max",
    "wellbeing_mean",
    "activity_seconds",
    "activity_seconds_by_hour",
    "peak_rss_mb",
}


def test_sim_run_passes_and_prints_json(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["sim", "run", str(SCENARIO_DIR / "user_request.yaml"), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["passed"] is True and out["scenario"] == "user_request"
    assert any(d["activity"] == "quiz" and d["action"] == "start" for d in out["decisions"])


def test_sim_run_fails_naming_the_expectation(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "s.yaml"
    path.write_text(
        "name: s\nduration_s: 5\ntimeline:\n  - {at: 0, leave: true}\n"
        "expect:\n  - {decision: {action: start, activity: quiz}}\n"
    )
    assert main(["sim", "run", str(path)]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"dms: {path}:6: expectation 0 failed: decision action=start")


def test_sim_run_bad_file_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "s.yaml"
    path.write_text("name: s\ntimeline:\n  - {at: 1, touch: {part: knee}}\n")
    assert main(["sim", "run", str(path)]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"dms: {path}:3: timeline.0.touch.part") and "\n" not in err


def test_study_json_has_the_contract_keys(capsys: pytest.CaptureFixture[str]) -> None:
    args = ["sim", "study", "--sessions", "2", "--minutes", "5", "--seed", "1", "--json"]
    assert main(args) == 0
    out = json.loads(capsys.readouterr().out)
    assert set(out) >= STUDY_KEYS
    assert set(out["failures"]) == FAILURE_KEYS
    assert out["sessions"] == 2
    assert out["activities_per_session"] > 0
    assert out["questions_per_session"] > 0


def test_study_prints_table_4(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["sim", "study", "--sessions", "1", "--minutes", "3", "--proactivity", "high"]) == 0
    out = capsys.readouterr().out
    for label in (
        "Questions per session",
        "User activities selection",
        "Speech recognition errors",
    ):
        assert label in out


def test_study_bad_proactivity(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["sim", "study", "--proactivity", "extreme"]) == 2  # a choice: usage error
    assert "--proactivity" in capsys.readouterr().err


def test_longterm_one_day_json_and_plots(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out_dir = tmp_path / "plots"
    args = ["sim", "longterm", "--days", "1", "--users", "2", "--out", str(out_dir), "--json"]
    assert main(args) == 0
    captured = capsys.readouterr()
    out = json.loads(captured.out)
    assert set(out) >= LONGTERM_KEYS
    assert out["days"] == 1
    assert set(out["activity_seconds_by_hour"]) == {str(h) for h in range(24)}
    total = sum(out["activity_seconds"].values())
    assert 0.9 * 86400 <= total <= 86400  # the robot is always doing something
    assert out["peak_rss_mb"] > 0
    assert "1/1" in captured.err and "time left" in captured.err  # the progress bar
    for name in ("drives.png", "timeline.png", "by_hour.png"):
        assert (out_dir / name).read_bytes()[:4] == b"\x89PNG"


def test_replay_of_a_missing_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["sim", "replay", str(tmp_path / "none.mcap")]) == 1
    assert "cannot read" in capsys.readouterr().err
