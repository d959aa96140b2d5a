"""``dms sim robot``: the simulated Mini as its own process over Zenoh.

For ``dms run --robot zenoh``: it executes every ``robot/command`` (an ``interrupt``
command stops its ``args.target``) and publishes ``robot/feedback`` (started, done,
interrupted, failed) as the simulated robot reports it, and its joint positions on
``robot/joints`` ten times a second (the daemon's frames follow them). It declares
``alive/robot/feedback`` and ``alive/robot/joints`` so the daemon knows the robot is there.
"""

from __future__ import annotations

import threading
from typing import Any

from pydantic import ValidationError

from dms.bus import ZenohClient
from dms.kernel import keys
from dms.kernel.clock import Clock, iso
from dms.kernel.messages import RobotCommand

POLL_S = 0.02
JOINTS_PERIOD_S = 0.1
"""How often the joint positions are published (a robot's joint states come at 10 Hz+)."""


class RobotNode:
    """A SimRobot answering over Zenoh until :attr:`stopped` is set."""

    def __init__(self, client: ZenohClient, clock: Clock, seed: int = 0) -> None:
        from sim.robot import SimRobot

        self.client = client
        self.clock = clock
        self.robot = SimRobot(rng_seed=seed)
        self.stopped = threading.Event()
        self._lock = threading.Lock()
        self.commands = 0
        self.feedback = 0
        self.joint_states = 0

    def _on_command(self, _key: str, payload: Any) -> None:
        try:
            command = RobotCommand.model_validate(payload)
        except ValidationError:
            return
        with self._lock:
            self.commands += 1
            now = self.clock.now()
            if command.action == "interrupt":
                target = command.args.get("target")
                if isinstance(target, str):
                    self.robot.interrupt(target, now)
            else:
                self.robot.send(command, now)

    def run(self, duration_s: float | None = None) -> None:
        """Serve until stopped (or for ``duration_s`` seconds)."""
        self.client.subscribe(keys.ROBOT_COMMAND, self._on_command)
        self.client.declare_token(keys.ALIVE_PREFIX + keys.ROBOT_FEEDBACK)
        self.client.declare_token(keys.ALIVE_PREFIX + keys.ROBOT_JOINTS)
        start = next_joints = self.clock.monotonic()
        while not self.stopped.wait(POLL_S):
            now = self.clock.now()
            with self._lock:
                out = self.robot.poll(now)
                joints = self.robot.joints(now)
            for feedback in out:
                self.client.publish(keys.ROBOT_FEEDBACK, feedback.model_dump(mode="json"))
                self.feedback += 1
            if self.clock.monotonic() >= next_joints:
                next_joints += JOINTS_PERIOD_S
                self.client.publish(keys.ROBOT_JOINTS, {"positions": joints, "time": iso(now)})
                self.joint_states += 1
            if duration_s is not None and self.clock.monotonic() - start >= duration_s:
                break
