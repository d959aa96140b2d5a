"""Over ten visits, a low, a moderate and a high persona each land in their own mode.

The robot is not told their proactivity: it asks the question on initiative and counts
who takes the chances it offers (memory/proactivity.py). The shipped personas visit a
real controller stack on the virtual clock (real SQLite, the simulated Mini); what the
store holds after the tenth visit is their estimated proactivity, and the mode follows.
"""

from __future__ import annotations

import random

import pytest

from dms.config import Settings
from dms.controller.choice import MODE_BY_PROACTIVITY
from sim.harness import Simulation
from sim.persona import load_persona
from sim.user import SimulatedUser
from tests.core.scripted import START

VISIT_S = 15 * 60.0
GAP_S = 3600.0


@pytest.mark.parametrize("name", ["bernard", "carmen", "alice"])
def test_a_persona_lands_in_the_mode_of_its_proactivity(name: str) -> None:
    persona = load_persona(name)
    settings = Settings.model_validate({"controller": {"feedback_probability": 0.0}})
    with Simulation(settings, seed=3, start=START) as sim:
        sim.idle_step_s = 10.0  # between visits nobody is there (see sim.harness)
        user = SimulatedUser(persona, random.Random(3))
        for _visit in range(10):
            sim.seat(user)
            sim.run_for(VISIT_S)
            sim.unseat()
            sim.run_for(GAP_S)
        profiles = sim.controller.deps.profiles
        assert profiles is not None
        profile = profiles.store.get(persona.id)
        assert profile is not None
        assert profile.initiative_offered >= 5, "enough chances to tell"
        assert profile.proactivity == persona.proactivity, (
            profile.initiative_taken,
            profile.initiative_offered,
        )
        sim.seat(user)  # an eleventh visit: its mode is the one the estimate gives
        sim.run_for(30.0)
        state = sim.controller.state
        assert state is not None and state.mode == MODE_BY_PROACTIVITY[persona.proactivity]
