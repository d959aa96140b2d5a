"""Where the robot should be at each instant, from the commands it is carrying out.

Three layers make the posture sent to Reachy Mini every control period:

- the **stance**: where an ``aim`` (``look_at``, ``point_at``, ``turn_to``) or a
  ``pose`` keyframe put the body, the head and the antennas; it moves toward its target
  at the contract's joint speeds, so a turn takes as long as the daemon expects;
- a **gesture** on top of it, offsets from the stance along a timeline
  (:mod:`dms_reachy.gestures`);
- an **LED pattern**, the antennas swinging around theirs.

:class:`Mixer` is pure and takes ``now`` (monotonic seconds): :meth:`Mixer.step` returns
the posture and the commands that finished. The bridge owns the clock, the SDK and the
bus, and holds its lock around every call.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

from dms_reachy import body, gestures
from dms_reachy.body import Posture

REST = Posture(right=-0.1745, left=0.1745)
"""The SDK's rest: head level and forward, antennas 10 degrees out (it steadies them)."""

SPEEDS: Mapping[str, float] = {
    "body_yaw": body.CONTRACT["hip"].speed,
    "yaw": body.CONTRACT["hip"].speed + body.CONTRACT["neck"].speed,
    "pitch": body.CONTRACT["head"].speed,
    "roll": 1.0,
    "z": 0.05,
    "right": body.CONTRACT["left_arm"].speed,
    "left": body.CONTRACT["left_arm"].speed,
}
"""How fast the stance moves, per axis (rad/s, m/s for z): the contract's joints' speeds
(the head's world yaw turns with the hip and the neck together)."""

REACHED = 1e-3
FADE_S = 0.3
"""An interrupted gesture eases back to the stance over this long (a robot that stopped
dead mid-nod would stay bowed)."""


@dataclass
class _Gesture:
    command_id: str | None
    """None for the fade after an interruption (nobody waits for it)."""
    keyframes: Sequence[gestures.Keyframe]
    started: float

    def offsets(self, now: float) -> dict[str, float]:
        return gestures.offsets_at(self.keyframes, now - self.started)

    def over(self, now: float) -> bool:
        return now - self.started >= gestures.length(self.keyframes)


@dataclass
class Mixer:
    """The three layers, and which command waits on which."""

    stance: Posture = REST
    target: Posture = REST
    stance_command: str | None = None
    """The ``aim`` or ``pose`` command done once the stance reaches its target."""
    gesture: _Gesture | None = None
    pattern: gestures.Pattern = field(default_factory=lambda: gestures.PATTERNS["solid"])
    pattern_started: float = 0.0
    last: float | None = None

    def aim(self, command_id: str, target: Posture, now: float) -> str | None:
        """Move the stance to ``target``; returns the stance command it replaces."""
        self._advance(now)
        replaced, self.stance_command = self.stance_command, command_id
        self.target = body.safe(target)
        return replaced

    def play(
        self, command_id: str, keyframes: Sequence[gestures.Keyframe], now: float
    ) -> str | None:
        """Play a gesture from ``now``; returns the gesture command it replaces."""
        self._advance(now)
        replaced = self.gesture.command_id if self.gesture is not None else None
        self.gesture = _Gesture(command_id, tuple(keyframes), now)
        return replaced

    def light(self, pattern: gestures.Pattern, now: float) -> None:
        self.pattern, self.pattern_started = pattern, now

    def stop(self, command_id: str, now: float) -> bool:
        """Stop the command if it is running here (True): a gesture eases back, a
        stance stays where it got to."""
        self._advance(now)
        if self.gesture is not None and self.gesture.command_id == command_id:
            current = self.gesture.offsets(now)
            self.gesture = _Gesture(None, ((0.0, current), (FADE_S, {})), now)
            return True
        if self.stance_command == command_id:
            self.stance_command, self.target = None, self.stance
            return True
        return False

    def running(self) -> list[str]:
        """The commands still moving the robot."""
        ids = [self.stance_command]
        if self.gesture is not None:
            ids.append(self.gesture.command_id)
        return [i for i in ids if i is not None]

    def hold(self, posture: Posture, now: float) -> list[str]:
        """Take ``posture`` as where the robot is (after the SDK moved it itself: sleep,
        wake); returns the commands this ends, which no longer move it."""
        ended = self.running()
        self.stance = self.target = replace(posture)
        self.stance_command, self.gesture, self.last = None, None, now
        return ended

    def step(self, now: float) -> tuple[Posture, list[str]]:
        """The posture to send at ``now`` and the commands done since the last step."""
        self._advance(now)
        done: list[str] = []
        if self.stance_command is not None and _distance(self.stance, self.target) < REACHED:
            done.append(self.stance_command)
            self.stance_command = None
        offsets: dict[str, float] = {}
        if self.gesture is not None:
            offsets = self.gesture.offsets(now)
            if self.gesture.over(now):
                if self.gesture.command_id is not None:
                    done.append(self.gesture.command_id)
                self.gesture, offsets = None, {}
        if not {"left", "right"} & set(offsets):
            for axis, value in self.pattern.offsets(now - self.pattern_started).items():
                offsets[axis] = offsets.get(axis, 0.0) + value
        return body.safe(self.stance.plus(offsets)), done

    def _advance(self, now: float) -> None:
        """Move the stance toward its target for the time since the last call."""
        if self.last is None:
            self.last = now
            return
        elapsed = max(0.0, now - self.last)
        self.last = now
        moved = {}
        for axis in body.AXES:
            here, there = getattr(self.stance, axis), getattr(self.target, axis)
            step = SPEEDS[axis] * elapsed
            moved[axis] = there if abs(there - here) <= step else here + step * _sign(there - here)
        self.stance = Posture(**moved)


def _distance(a: Posture, b: Posture) -> float:
    return max(abs(float(getattr(a, axis)) - float(getattr(b, axis))) for axis in body.AXES)


def _sign(value: float) -> float:
    return 1.0 if value > 0 else -1.0
