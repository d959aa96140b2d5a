"""``--out DIR``: the study's raw data reads back (sessions.csv, decisions.csv, table4.png)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from dms.cli import main
from sim.export import DECISION_COLUMNS, SESSION_COLUMNS

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def test_study_out_writes_sessions_decisions_and_the_figure(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run"
    args = ["sim", "study", "--sessions", "2", "--minutes", "8", "--out", str(out), "--json"]
    assert main(args) == 0
    summary = json.loads(capsys.readouterr().out)  # stdout is JSON alone: progress is on stderr
    with (out / "sessions.csv").open(newline="") as handle:
        sessions = list(csv.DictReader(handle))
    assert tuple(sessions[0]) == SESSION_COLUMNS
    assert [row["participant"] for row in sessions] == ["p01", "p02"]
    mean_questions = sum(float(row["questions_per_session"]) for row in sessions) / 2
    assert mean_questions == summary["questions_per_session"]
    with (out / "decisions.csv").open(newline="") as handle:
        decisions = list(csv.DictReader(handle))
    assert tuple(decisions[0]) == DECISION_COLUMNS
    assert {row["session"] for row in decisions} == {"1", "2"}
    starts = [row for row in decisions if row["action"] == "start" and row["chosen_by"] == "robot"]
    assert starts, "a robot choice in 16 minutes"
    for row in decisions:
        if row["why"]:
            assert isinstance(json.loads(row["why"]), dict)
    assert (out / "table4.png").read_bytes()[:8] == PNG_MAGIC
    assert not (out / "adaptation.png").exists()  # one visit each: nothing to adapt over


def test_returning_participants_get_the_adaptation_figure(tmp_path: Path) -> None:
    from sim.export import write_all
    from sim.study import SessionMetrics

    sessions = [
        SessionMetrics(
            participant=f"p{person}",
            visit=visit,
            robot_decisions=2,
            robot_choice_cancels=1 if visit == 1 else 0,
            kendall_tau=0.5 + 0.1 * visit,
        )
        for visit in (1, 2, 3)
        for person in (1, 2)
    ]
    paths = write_all(tmp_path, sessions, [])
    assert paths[-1] == tmp_path / "adaptation.png"
    assert paths[-1].read_bytes()[:8] == PNG_MAGIC
