"""Every shipped scenario runs through the real stack and all its expectations hold."""

from __future__ import annotations

from pathlib import Path

import pytest

from sim.runner import run_scenario
from sim.scenario import shipped_scenarios


@pytest.mark.parametrize("path", shipped_scenarios(), ids=lambda p: p.stem)
def test_shipped_scenario(path: Path) -> None:
    result = run_scenario(path)
    failure = result.first_failure
    assert failure is None, (
        f"{path.name}:{failure.line}: {failure.description}: {failure.detail}" if failure else ""
    )
    assert result.decisions, "a scenario that decides nothing tests nothing"


def test_a_failed_expectation_is_named(tmp_path: Path) -> None:
    path = tmp_path / "wrong.yaml"
    path.write_text(
        "name: wrong\nduration_s: 20\n"
        "settings: {controller: {session_questions: 0, feedback_probability: 0}}\n"
        'timeline:\n  - {at: 0, arrive: {user: alice}}\n  - {at: 2, say: "let\'s play bingo"}\n'
        "expect:\n"
        "  - {decision: {action: start, activity: bingo}, within: [2, 3]}\n"
        "  - {decision: {action: start, activity: quiz}, within: [2, 3]}\n"
    )
    result = run_scenario(path)
    assert not result.passed
    failure = result.first_failure
    assert failure is not None and failure.index == 1 and failure.line == 9
    assert "activity=quiz" in failure.description
    assert "bingo" in failure.detail  # what was seen instead
