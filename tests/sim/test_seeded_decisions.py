"""Seeded simulations decide exactly what they decided before.

A refactoring of the controller must leave every decision of a seeded run as it was:
the same decisions at the same virtual times, with the same reasons and the same
``why`` (the draws included), down to the byte. Each run's decisions are hashed as the
simulator gives them (the virtual time and the decision's JSON, one line each) and
compared with the hash the code gave when it was last meant to decide this way.

A change that is meant to change decisions (a new rule, another calibration) changes
these hashes: run this file, check that the runs' decisions changed as intended, and
put the new hashes here in the same commit, saying why in its message.
"""

from __future__ import annotations

import hashlib
from collections.abc import Iterator
from typing import Any

import pytest

from dms.config import Settings
from sim import harness
from sim.baselines import ChooserName
from sim.harness import TimedDecision
from sim.longterm import run_longterm
from sim.study import run_study, study_settings

STUDY = {
    "dms": "5d8570beafad1ebe7ef2581d538c99f02aaf4c9a8f750bbeb87636d03ed7e618",
    "explore": "7189a158508cdf1e04f291c501522ff9e11de28bf30a801c57ea886aa49ee281",
    "random": "8c04351369d972bde4b3fa3ed75032f7b4c387ad4c19419dccdf9bf756eb0c2e",
}
"""Three participants of 30 minutes, seed 0, by the chooser that picks the robot's
activities (a baseline's draws are its own: its decisions explain less)."""

LONGTERM = "1e5fdb3588e08daf2a218b439e3c9cc478d61c706b4b442c0016e5f660e62838"
"""Three days of robot life with three users visiting, seed 0."""


@pytest.fixture
def digest(monkeypatch: pytest.MonkeyPatch) -> Iterator[Any]:
    """A sha256 fed every decision of every simulation made while the test runs."""
    sha = hashlib.sha256()
    made = harness.Simulation.__init__

    def hashing(self: harness.Simulation, *args: Any, **kwargs: Any) -> None:
        made(self, *args, **kwargs)

        def note(timed: TimedDecision) -> None:
            sha.update(f"{timed.t!r} {timed.decision.model_dump_json()}\n".encode())

        self.decision_listeners.append(note)

    monkeypatch.setattr(harness.Simulation, "__init__", hashing)
    yield sha


@pytest.mark.parametrize("chooser", sorted(STUDY))
def test_a_seeded_study_decides_as_before(digest: Any, chooser: ChooserName) -> None:
    run_study(3, 30.0, "moderate", 0, study_settings(Settings(), {}), chooser=chooser)
    assert digest.hexdigest() == STUDY[chooser]


def test_a_seeded_longterm_run_decides_as_before(digest: Any) -> None:
    run_longterm(3, 3, 0, None)
    assert digest.hexdigest() == LONGTERM
