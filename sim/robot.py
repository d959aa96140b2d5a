"""The simulated Mini: executes robot commands with plausible durations.

It implements :class:`dms.kernel.ports.RobotPort`. Every command reports ``started`` at once,
then ``done`` when its duration has passed on the caller's clock: speech by word count
at the speaking rate, media by ``args.duration_s``, motions from a table, screen and
LED commands immediately. ``interrupt`` stops a command (``interrupted``). The
controller's clock here is its steady time (:class:`dms.kernel.clock.SteadyTime`): a
wall clock set back does not hold a command for the hour, nor one set forward end it.

**A body.** Its five joints (:class:`sim.body.SimBody`) move at their speeds toward the
``joints`` a command carries: an ``aim`` command (``look_at``, ``point_at``, ``turn_to``)
takes as long as the farthest joint needs, a gesture may carry joints too.
:meth:`SimRobot.joints` is the joint state at ``now``, what ``robot/joints`` reports.
An interrupted motion leaves the joints where they are.
:meth:`SimRobot.set_fault` makes a channel fail its commands or drop them (never
acknowledge), to test that the expression arbiter times them out.

**Launching an activity.** On the Mini, starting an activity launches its own process,
which loads its content before its first command plays; the paper's 3.78 s loading time
includes it. :attr:`SimRobot.launch_delay_s` models that robot-side cost: when
:attr:`SimRobot.process_of` (set by the simulation, which knows each command's source)
names a process the robot has not launched yet, that command and every other command
of the process wait until the launch is over before they start. No delay by default
(scenarios time their expectations on an instant robot); studies set one.
"""

from __future__ import annotations

import random
from collections import deque
from collections.abc import Callable, Hashable
from dataclasses import dataclass
from datetime import datetime, timedelta
from typing import Literal

from dms.kernel.body import JOINTS
from dms.kernel.messages import FeedbackStatus, RobotCommand, RobotFeedback
from sim.body import SimBody

Fault = Literal["fail", "hang", "stall"]

MOTION_SECONDS: dict[str, float] = {
    "nod": 1.5,
    "shake_head": 1.5,
    "wave": 2.5,
    "bow": 2.0,
    "look_around": 3.0,
    "think": 2.0,
    "celebrate": 3.0,
    "shrug": 1.5,
    "sleep_pose": 2.0,
    "wake_up": 2.0,
    "dance_step": 4.0,
    "clap": 2.0,
}
"""How long each gesture takes; unknown gestures take ``DEFAULT_MOTION_S``."""

SETTLE_S = 0.05
"""The shortest aiming motion: a target already reached is reported done at once."""

DEFAULT_MOTION_S = 2.0
DEFAULT_MEDIA_S = 30.0
DEFAULT_WPM = 150.0
LOG_KEPT = 1000
LAUNCHED_KEPT = 16
"""Launched processes remembered (an activity paused and resumed is not launched again)."""


@dataclass
class _Running:
    command: RobotCommand
    ends: datetime


class SimRobot:
    """An in-process robot on the caller's clock (real or virtual)."""

    def __init__(
        self,
        rng_seed: int = 0,
        speaking_rate_wpm: float = DEFAULT_WPM,
        launch_delay_s: tuple[float, float] = (0.0, 0.0),
    ) -> None:
        if speaking_rate_wpm <= 0:
            raise ValueError("speaking_rate_wpm must be positive")
        low, high = launch_delay_s
        if not 0.0 <= low <= high:
            raise ValueError("launch_delay_s must be (min, max) with 0 <= min <= max")
        self.rng = random.Random(rng_seed)
        self.speaking_rate_wpm = speaking_rate_wpm
        self.launch_delay_s = (float(low), float(high))
        """Seconds (drawn uniformly in [min, max]) to launch an activity's process."""
        self.process_of: Callable[[RobotCommand], Hashable | None] | None = None
        """Which activity process sends ``command`` (None: the robot's own, never launched)."""
        self._ready_at: dict[Hashable, datetime] = {}
        self.launches = 0
        self._running: dict[str, _Running] = {}
        self._out: list[tuple[datetime, int, RobotFeedback]] = []
        self._seq = 0
        self._faults: dict[str, Fault] = {}
        self.log: deque[tuple[datetime, RobotCommand]] = deque(maxlen=LOG_KEPT)
        """The last :data:`LOG_KEPT` commands received, with when: for tests and the stepper
        (all of them grew the daemon's ``--robot sim`` by a megabyte a simulated day)."""
        self.screen: dict[str, object] = {}
        """What the screen shows now (the last ``show``)."""
        self.leds: dict[str, object] = {}
        self.body: SimBody | None = None
        """The joints, made on the first motion or :meth:`joints` (it needs a clock)."""
        self.media_s: float | None = None
        """Seconds every media item plays, whatever its ``duration_s`` (None: its own):
        a study's media length is its input, not the shipped content's."""

    # ------------------------------------------------------------ faults

    def set_fault(self, channel: str, fault: Fault | None) -> None:
        """From now on, ``channel``'s commands fail (``fail``), are never acknowledged
        (``hang``) or start and never finish (``stall``); ``None`` heals it.
        ``channel="*"`` applies to every channel."""
        if fault is None:
            self._faults.pop(channel, None)
        else:
            self._faults[channel] = fault

    def _fault(self, channel: str) -> Fault | None:
        return self._faults.get(channel, self._faults.get("*"))

    # ------------------------------------------------------------ the port

    def duration(self, command: RobotCommand) -> float:
        """Seconds ``command`` takes on this robot."""
        args = command.args
        if command.channel == "speech":
            words = len(str(args.get("text", "")).split())
            rate = args.get("rate_wpm")
            wpm = float(rate) if isinstance(rate, int | float) and 40 <= rate <= 400 else None
            return 0.3 + 60.0 * words / (wpm or self.speaking_rate_wpm)
        if command.channel == "media":
            if self.media_s is not None:
                return self.media_s
            return _seconds(args.get("duration_s"), DEFAULT_MEDIA_S)
        if command.channel == "aim":
            return SETTLE_S
        if command.channel == "motion":
            name = str(args.get("name", ""))
            base = MOTION_SECONDS.get(name, DEFAULT_MOTION_S)
            return _seconds(args.get("duration_s"), base)
        return 0.0

    def _launched(self, command: RobotCommand, now: datetime) -> datetime:
        """When ``command``'s process is ready: now, or when its launch is over."""
        low, high = self.launch_delay_s
        if high <= 0.0 or self.process_of is None:
            return now
        process = self.process_of(command)
        if process is None:
            return now
        ready = self._ready_at.get(process)
        if ready is None:
            self.launches += 1
            delay = low if high <= low else self.rng.uniform(low, high)
            ready = now + timedelta(seconds=delay)
            self._ready_at[process] = ready
            while len(self._ready_at) > LAUNCHED_KEPT:
                del self._ready_at[next(iter(self._ready_at))]
        return max(now, ready)

    def send(self, command: RobotCommand, now: datetime) -> None:
        self.log.append((now, command))
        fault = self._fault(command.channel)
        if fault == "hang":
            return
        begins = self._launched(command, now)
        self._emit(begins, command.id, "started")
        if fault == "fail":
            self._emit(begins, command.id, "failed", "simulated fault")
            return
        if fault == "stall":
            return
        if command.channel == "screen":
            self.screen = {"action": command.action, **command.args}
        elif command.channel == "led":
            self.leds = {"action": command.action, **command.args}
        seconds = self.duration(command)
        if command.channel in ("motion", "aim"):
            seconds = max(seconds, self._aim(command, begins))
        ends = begins + timedelta(seconds=seconds)
        self._running[command.id] = _Running(command, ends)

    def joints(self, now: datetime) -> dict[str, float]:
        """The joint positions at ``now`` (what ``robot/joints`` reports)."""
        return self._body(now).advance(now)

    def _body(self, now: datetime) -> SimBody:
        if self.body is None:
            self.body = SimBody(now)
        return self.body

    def _aim(self, command: RobotCommand, begins: datetime) -> float:
        """Turn the joints a motion names toward their targets from ``begins``; the
        seconds the farthest needs (0 for a motion that names none)."""
        wanted = command.args.get("joints")
        if not isinstance(wanted, dict):
            return 0.0
        targets = {
            name: float(angle)
            for name, angle in wanted.items()
            if name in JOINTS and isinstance(angle, int | float) and not isinstance(angle, bool)
        }
        if not targets:
            return 0.0
        body = self._body(begins)
        body.aim(targets, begins)
        return max(
            abs(body.targets[name] - body.positions[name]) / JOINTS[name].speed for name in targets
        )

    def interrupt(self, command_id: str, now: datetime) -> None:
        running = self._running.get(command_id)
        moves = running is not None and running.command.channel in ("motion", "aim")
        if moves and self.body is not None:
            self.body.aim(self.body.advance(now), now)  # stop where the joints are
        if self._running.pop(command_id, None) is not None:
            # a command still waiting for its launch never reports that it started
            self._out = [i for i in self._out if i[2].id != command_id or i[0] <= now]
            self._emit(now, command_id, "interrupted")

    def poll(self, now: datetime) -> list[RobotFeedback]:
        ended = [key for key, running in self._running.items() if running.ends <= now]
        for command_id in ended:
            running = self._running.pop(command_id)
            self._emit(running.ends, command_id, "done")
        due = sorted(item for item in self._out if item[0] <= now)
        self._out = [item for item in self._out if item[0] > now]
        return [feedback for _, _, feedback in due]

    @property
    def busy(self) -> list[RobotCommand]:
        """The commands executing now."""
        return [running.command for running in self._running.values()]

    def _emit(
        self, when: datetime, command_id: str, status: FeedbackStatus, detail: str | None = None
    ) -> None:
        self._seq += 1
        feedback = RobotFeedback(id=command_id, status=status, detail=detail)
        self._out.append((when, self._seq, feedback))


def _seconds(value: object, default: float) -> float:
    if isinstance(value, int | float) and not isinstance(value, bool) and value >= 0:
        return float(value)
    return default
