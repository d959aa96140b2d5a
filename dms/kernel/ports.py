"""Ports: what the controller and the activities need from the outside world.

Each port has a simulated implementation (``sim.robot.SimRobot``) and a real one
(``dms.bus`` for Zenoh). The controller and activities only see these protocols,
so they run the same on the virtual clock and live.
"""

from __future__ import annotations

from collections.abc import Callable
from datetime import datetime
from typing import Protocol, runtime_checkable

from dms.kernel.messages import RobotCommand, RobotFeedback


class RobotPort(Protocol):
    """Executes robot commands and reports on them.

    ``send`` never blocks. The robot answers with :class:`RobotFeedback` messages
    (``started``, then ``done``, ``interrupted`` or ``failed``), collected by ``poll``.
    """

    def send(self, command: RobotCommand, now: datetime) -> None:
        """Start executing ``command``."""
        ...

    def interrupt(self, command_id: str, now: datetime) -> None:
        """Stop ``command_id`` if it still runs; it then reports ``interrupted``."""
        ...

    def poll(self, now: datetime) -> list[RobotFeedback]:
        """Feedback that arrived since the last poll, oldest first."""
        ...


@runtime_checkable
class JointReporter(Protocol):
    """A robot in the daemon's process that can say where its joints are (the simulated
    Mini): the daemon publishes it on ``robot/joints`` and the scene follows it."""

    def joints(self, now: datetime) -> dict[str, float]:
        """The joint positions (radians) at ``now``."""
        ...


CommandListener = Callable[[RobotCommand], None]
"""Told of every command sent to the robot (the daemon publishes them on ``robot/command``)."""
