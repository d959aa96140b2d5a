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
    "dms": "e78ff5f98cef8a501ac12164c994f2aabafb7db5f2b02f7bc0e6f6ebfb347e28",
    "explore": "3b96a12857c04abc361bd706aac8833593c216228efe6bb3c3bbecdf212b2722",
    "random": "71ec5e33f1935aa49faec568dcb45c29ad5c67b32ca615d1dd6b64c3091b275d",
}
"""Three participants of 30 minutes, seed 0, by the chooser that picks the robot's
activities (a baseline's draws are its own: its decisions explain less)."""

LONGTERM = "a95820524148acbaacd3f667510f8e98a2431262a049da1de09f0c12912aece5"
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
