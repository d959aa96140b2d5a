"""``dms sim compare``: two designs on the same participants, paired differences."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from dms.cli import main

ARGS = ["--sessions", "6", "--minutes", "15", "--seed", "2", "--json"]


def _compare(capsys: pytest.CaptureFixture[str], a: Path, b: Path) -> dict[str, dict[str, object]]:
    assert main(["sim", "compare", str(a), str(b), *ARGS]) == 0
    out = json.loads(capsys.readouterr().out)
    metrics: dict[str, dict[str, object]] = out["metrics"]
    return metrics


def _ci(metric: dict[str, object]) -> tuple[float, float]:
    low, high = metric["ci"]  # type: ignore[misc]
    return float(low), float(high)


def test_compare_finds_a_difference_between_designs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    a, b = tmp_path / "a.toml", tmp_path / "b.toml"
    a.write_text("[controller]\nsession_questions = 4\n")
    b.write_text("[controller]\nsession_questions = 1\n")
    metrics = _compare(capsys, a, b)
    assert set(metrics) >= {"questions_per_session", "activity_time_s", "cancels_per_session"}
    questions = metrics["questions_per_session"]
    assert questions["a"] == 4.0 and questions["b"] == 1.0
    low, high = _ci(questions)
    assert high < 0.0, (low, high)  # B asks fewer: the interval excludes 0


def test_compare_of_identical_designs_covers_zero(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    a, b = tmp_path / "a.toml", tmp_path / "b.toml"
    a.write_text("[controller]\nfeedback_probability = 0.5\n")
    b.write_text("[controller]\nfeedback_probability = 0.5\n")
    metrics = _compare(capsys, a, b)
    assert metrics["change_time_s"]["ci"] is not None  # 15 minutes hold two activities
    for name, metric in metrics.items():
        if metric["ci"] is None:  # no session pair has it (no stop was asked for)
            assert metric["a"] is None and metric["b"] is None, (name, metric)
            continue
        low, high = _ci(metric)
        assert low <= 0.0 <= high, (name, metric)
