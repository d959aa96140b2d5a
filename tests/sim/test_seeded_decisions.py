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
    "dms": "4bfa6389c8f5a63c6154279e5dfec351a64bec85496c3a378f86f51e3d9e5c09",
    "random": "e0150b14d16ba0d77bd8b4fa695dfd5dde29a3998371cb8f2ca13b5cb71e2baa",
}
"""Three participants of 30 minutes, seed 0, by the chooser that picks the robot's
activities (a baseline's draws are its own: its decisions explain less)."""

LONGTERM = "c9dfa974f4598d5964605c82f6128879c86447fd0e83b1098856b0ee44d444c1"
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
