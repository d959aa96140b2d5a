"""The manager level: five managers, each running the activities of its group."""

from managers.base import Manager, ManagerReply, ManagerStatus
from managers.groups import (
    CognitiveManager,
    EntertainmentManager,
    GeneralManager,
    RelaxManager,
    SocialManager,
    make_managers,
)

__all__ = [
    "CognitiveManager",
    "EntertainmentManager",
    "GeneralManager",
    "Manager",
    "ManagerReply",
    "ManagerStatus",
    "RelaxManager",
    "SocialManager",
    "make_managers",
]
