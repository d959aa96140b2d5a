"""A long-term run's idle steps may share one prediction of the motivated behavior
(``Simulation.prediction_s``, issue 14): the run must be the same as with one
prediction per idle step, tick for tick and decision for decision."""

from __future__ import annotations

import pytest

from sim import longterm


def test_shared_predictions_change_nothing(monkeypatch: pytest.MonkeyPatch) -> None:
    shared = longterm.run_longterm(days=3, users=2, seed=5)
    monkeypatch.setattr(longterm, "PREDICTION_S", 0.0)  # one prediction per idle step
    own = longterm.run_longterm(days=3, users=2, seed=5)
    assert shared.ticks == own.ticks
    assert shared.decision_rows == own.decision_rows
    assert shared.spans == own.spans
    assert shared.samples == own.samples
    shared_json, own_json = shared.to_json(), own.to_json()
    for figures in (shared_json, own_json):
        figures.pop("wall_s")
        figures.pop("peak_rss_mb")
    assert shared_json == own_json
