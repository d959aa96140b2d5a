"""The manager level: five managers, each running the activities of its group."""

from managers.base import Manager, ManagerReply, ManagerStatus
from managers.groups import EntertainmentManager, make_managers

__all__ = [
    "EntertainmentManager",
    "Manager",
    "ManagerReply",
    "ManagerStatus",
    "make_managers",
]
