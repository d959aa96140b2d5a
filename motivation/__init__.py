"""The robot's artificial biology: drives, stimuli, motivations, the dominant one, wellbeing.

``MotivationModel`` is pure: the controller steps it once a tick with the stimuli it
builds from the inputs; simulations jump ahead with ``advance`` and ``simulate``.
"""

from motivation.config import (
    DEFAULT_DRIVES,
    DriveConfig,
    MotivationConfig,
    MotivationConfigError,
    StimulusConfig,
    load_config,
)
from motivation.model import NO_DOMINANT, MotivationModel, MotivationState
from motivation.stimuli import Percepts, Stimuli
from motivation.trajectory import Run, advance, simulate

__all__ = [
    "DEFAULT_DRIVES",
    "NO_DOMINANT",
    "DriveConfig",
    "MotivationConfig",
    "MotivationConfigError",
    "MotivationModel",
    "MotivationState",
    "Percepts",
    "Run",
    "Stimuli",
    "StimulusConfig",
    "advance",
    "load_config",
    "simulate",
]
