"""A real controller stack on a virtual clock with a scripted user, for tests that say
exactly what the user does: no opening or feedback questions unless a test asks."""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Any

from dms.config import Settings
from dms.kernel import keys
from dms.kernel.messages import UserPerception
from sim.harness import Simulation

START = datetime(2026, 11, 23, 10, 0, tzinfo=UTC)
ANN = UserPerception(present=True, user_id="ann", ready=True, engagement=0.8)

QUIET = {"session_questions": 0, "question_every": 0, "feedback_probability": 0.0}
"""The controller asks nothing of its own accord."""


def quiet_settings(controller: dict[str, Any] | None = None, **top: Any) -> Settings:
    """Settings with :data:`QUIET` (``controller`` entries win) and top-level ``top``."""
    return Settings.model_validate({**top, "controller": {**QUIET, **(controller or {})}})


def seated(settings: Settings, seed: int = 4, start: datetime = START) -> Simulation:
    """A simulation with Ann seated in front of the robot, perceived every tick."""
    sim = Simulation(settings, seed=seed, start=start)
    sim.presence = ANN
    sim.feed(keys.PERCEPTION_USER, ANN)
    return sim
