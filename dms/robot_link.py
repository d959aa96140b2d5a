"""The robot port for an external robot reached over Zenoh (``--robot zenoh``).

Commands already go out on ``robot/command`` (the daemon publishes every command,
whatever the robot); this port only collects the robot's ``robot/feedback`` and asks
for interruptions. A command the robot never acknowledges is timed out by the
expression arbiter, which fails the activity cleanly.
"""

from __future__ import annotations

import itertools
import threading
from collections import deque
from collections.abc import Callable
from datetime import datetime

from dms.kernel.messages import RobotCommand, RobotFeedback

_interrupts = itertools.count(1)


class ZenohRobot:
    """A RobotPort whose feedback arrives from the bus's threads."""

    def __init__(self, publish_command: Callable[[RobotCommand], None]) -> None:
        self._publish = publish_command
        self._lock = threading.Lock()
        self._feedback: deque[RobotFeedback] = deque(maxlen=4096)
        self._channels: dict[str, str] = {}

    def send(self, command: RobotCommand, now: datetime) -> None:
        self._channels[command.id] = command.channel

    def interrupt(self, command_id: str, now: datetime) -> None:
        channel = self._channels.get(command_id, "speech")
        self._publish(
            RobotCommand(
                id=f"interrupt-{next(_interrupts)}",
                channel=channel,
                action="interrupt",
                args={"target": command_id},
            )
        )

    def feed(self, feedback: RobotFeedback) -> None:
        """Called by the bus with each validated ``robot/feedback``."""
        with self._lock:
            self._feedback.append(feedback)

    def poll(self, now: datetime) -> list[RobotFeedback]:
        with self._lock:
            out = list(self._feedback)
            self._feedback.clear()
        for feedback in out:
            if feedback.status in ("done", "interrupted", "failed"):
                self._channels.pop(feedback.id, None)
        return out
