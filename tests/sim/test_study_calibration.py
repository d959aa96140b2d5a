"""The study's inputs are calibrated apart from what it predicts.

Every input in sim/calibration.py names its source (a passage of the paper or an
assumption); one that was first fitted to a row of Table 4 says so, and that row is then
reported as an input. The table's values appear in the simulator's code only where a
study is reported beside the paper.
"""

from __future__ import annotations

import ast
from pathlib import Path

from sim.calibration import DEFAULT, INPUTS, PARTICIPANT_INPUTS
from sim.table4 import INPUT_METRICS, PAPER

SIM = Path(__file__).resolve().parents[2] / "sim"
REPORTING = {"table4.py"}
"""The one module that holds the paper's Table 4, to report beside it."""


def test_every_input_names_a_source_that_is_not_a_table4_metric() -> None:
    for name, item in INPUTS.items():
        assert item.source.startswith(("paper,", "assumed:")), (name, item.source)
        if "Table 4" in item.source:
            # Only the failure counts may be read, or a row an input was first fitted to;
            # either row is then reported as an input, not a prediction.
            assert "Table 4 failures" in item.source or "first fitted to" in item.source, (
                name,
                item.source,
            )
            assert "input" in item.source, (name, item.source)
    assert {"speech_recognition_errors", "user_not_answering"} <= set(INPUT_METRICS)
    assert "first fitted" in INPUT_METRICS["activity_load_time_s"]


def test_no_input_value_is_a_table4_mean() -> None:
    figures = {mean for mean, _sd in PAPER.values()}
    for name, value in DEFAULT.values:
        numbers = value if isinstance(value, tuple) else (value,)
        for number in numbers:
            assert round(float(number), 2) not in figures, (name, number)


def test_the_simulator_uses_table4_means_only_where_it_reports_them() -> None:
    means = {mean for mean, _sd in PAPER.values()}
    offenders = []
    for path in SIM.rglob("*.py"):
        if path.name in REPORTING:
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Constant) and node.value in means:
                offenders.append(f"{path.name}:{node.lineno}: {node.value}")
    assert not offenders, offenders


def test_every_participant_input_can_be_moved() -> None:
    for name in PARTICIPANT_INPUTS:
        assert INPUTS[name].kind == "participant"
        moved = DEFAULT.scaled(name, 1.5)[name]
        assert moved != DEFAULT[name] or DEFAULT[name] in (0, 0.0), name
