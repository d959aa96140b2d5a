"""The one module that calls Pollen Robotics' SDK: connect, move, read, sleep, wake.

Every call may raise when the robot's daemon is gone (a closed WebSocket, a refused
connection, a reply that never comes): the bridge catches :class:`RobotGone`, which
wraps them, and reconnects. The SDK is imported on first use, so the pure modules and
their tests do without it.
"""

from __future__ import annotations

import contextlib
import math
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from dms_reachy.body import Posture

CONNECT_TIMEOUT_S = 3.0
CLOSE_TIMEOUT_S = 2.0
LOCAL = frozenset({"localhost", "127.0.0.1", "::1"})
FACES_WEIGHT = 0.001
"""The SDK blends its tracking aim into the head's target by this weight."""


class RobotGone(Exception):
    """The robot's daemon did not answer (gone, restarting, never there)."""


@dataclass(frozen=True, slots=True)
class Measured:
    """The robot's measured body yaw and head yaw and pitch (radians, world frame)."""

    body_yaw: float
    yaw: float
    pitch: float
    roll: float
    z: float
    right: float
    left: float

    def posture(self) -> Posture:
        return Posture(
            self.body_yaw, self.yaw, self.pitch, self.roll, self.z, self.right, self.left
        )


def head_angles(matrix: Any) -> tuple[float, float, float]:
    """Roll, pitch and yaw of a 4x4 head pose (the SDK's extrinsic xyz convention)."""
    r = matrix
    pitch = -math.asin(max(-1.0, min(1.0, float(r[2][0]))))
    yaw = math.atan2(float(r[1][0]), float(r[0][0]))
    roll = math.atan2(float(r[2][1]), float(r[2][2]))
    return roll, pitch, yaw


class Reachy:
    """A connection to one Reachy Mini daemon (``host:port``)."""

    def __init__(self, host: str, port: int, media: bool) -> None:
        self.host, self.port, self.media = host, port, media
        self._mini: Any = None
        self._adopted: Any = None
        self._owned = True
        """False for the dashboard's connection, which the dashboard closes."""

    @classmethod
    def adopt(cls, mini: Any, media: bool) -> Reachy:
        """A connection the robot's dashboard made (an app's): used first, left to the
        dashboard to close; after a loss the bridge connects again on its own."""
        reachy = cls(str(mini.host), int(mini.port), media)
        reachy._adopted = mini
        return reachy

    @property
    def where(self) -> str:
        return f"{self.host}:{self.port}"

    @property
    def connected(self) -> bool:
        return self._mini is not None

    def connect(self) -> None:
        """Connect (media as asked); raises RobotGone with the SDK's reason."""
        if self._adopted is not None:
            self._mini, self._adopted = self._adopted, None
            self._owned = False
            return
        self._owned = True
        try:
            from reachy_mini import ReachyMini

            self._mini = ReachyMini(
                host=self.host,
                port=self.port,
                # never "auto": it would look for robots by mDNS when the host fails
                connection_mode="localhost_only" if self.host in LOCAL else "network",
                media_backend="default" if self.media else "no_media",
                timeout=CONNECT_TIMEOUT_S,
                automatic_body_yaw=False,  # the bridge turns the body itself (the hip)
            )
        except Exception as error:  # the SDK raises anything from OSError to TimeoutError
            self._mini = None
            raise RobotGone(_reason(error)) from error

    def close(self) -> None:
        mini, self._mini = self._mini, None
        if mini is None or not self._owned:
            return

        def disconnect() -> None:
            # the SDK's disconnect (and its __del__) may wait on a socket that is gone
            with contextlib.suppress(Exception):
                mini.client.disconnect()

        closer = threading.Thread(target=disconnect, name="reachy-close", daemon=True)
        closer.start()
        closer.join(CLOSE_TIMEOUT_S)

    def _call(self, method: str, *args: Any, **kwargs: Any) -> Any:
        if self._mini is None:
            raise RobotGone("not connected")
        try:
            return getattr(self._mini, method)(*args, **kwargs)
        except Exception as error:
            raise RobotGone(_reason(error)) from error

    def send(self, posture: Posture) -> None:
        """One target for every axis (the SDK's ``set_target``, which returns at once)."""
        from reachy_mini.utils import create_head_pose

        head = create_head_pose(
            z=posture.z, roll=posture.roll, pitch=posture.pitch, yaw=posture.yaw, degrees=False
        )
        self._call(
            "set_target",
            head=head,
            antennas=[posture.right, posture.left],
            body_yaw=posture.body_yaw,
        )

    def measure(self) -> Measured:
        """The measured joints and head, from the SDK's latest state. Raises RobotGone
        when that state has stopped coming: the SDK keeps the last one, so a robot
        asleep (sent nothing) would otherwise look present after its daemon went."""
        if self._mini is not None and not getattr(self._mini.client, "_is_alive", True):
            raise RobotGone("no state from the robot's daemon for a second")
        joints, antennas = self._call("get_current_joint_positions")
        matrix = self._call("get_current_head_pose")
        roll, pitch, yaw = head_angles(matrix)
        return Measured(
            body_yaw=float(joints[0]),
            yaw=yaw,
            pitch=pitch,
            roll=roll,
            z=float(matrix[2][3]),
            right=float(antennas[0]),
            left=float(antennas[1]),
        )

    def head_pose(self) -> Any:
        """The head's 4x4 pose in Reachy's world frame (the neutral head origin)."""
        return self._call("get_current_head_pose")

    def gravity_compensation(self, on: bool) -> None:
        """The head's motors carrying only its weight (a hand moves it), or back to
        holding their targets. The SDK's simulator takes the ask and keeps its motors as
        they are (it has no motor modes)."""
        self._call("enable_gravity_compensation" if on else "disable_gravity_compensation")

    def track_faces(self) -> None:
        """Start the daemon's face detection (its head tracking) at ``weight``: above 0
        or it does not detect; this small, the head stays the bridge's to move. A robot
        without a camera says so in its daemon's log and finds no face."""
        self._call("start_head_tracking", weight=FACES_WEIGHT)

    def tracked_face(self) -> tuple[float, float] | None:
        """The face the daemon found last, ``x`` and ``y`` across its image (-1..1), or
        None (no face now, or no state from the daemon yet)."""
        if self._mini is None:
            raise RobotGone("not connected")
        try:
            face = self._mini.get_tracked_face(wait=False)
        except AssertionError:  # the SDK's way of saying no state has come yet
            return None
        except Exception as error:
            raise RobotGone(_reason(error)) from error
        if not face.detected or face.x is None or face.y is None:
            return None
        return float(face.x), float(face.y)

    def goto_sleep(self) -> None:
        self._call("goto_sleep")

    def wake_up(self) -> None:
        self._call("wake_up")

    def play(self, sound: Path) -> None:
        """Play a WAV file on the robot's speaker (returns while it plays)."""
        if self._mini is None:
            raise RobotGone("not connected")
        try:
            self._mini.media.play_sound(str(sound))
        except Exception as error:
            raise RobotGone(_reason(error)) from error

    def stop_sound(self) -> None:
        if self._mini is None:
            return
        with contextlib.suppress(Exception):  # nothing playing, or gone: quiet either way
            self._mini.media.stop_playing()


def _reason(error: BaseException) -> str:
    text = " ".join(str(error).split())[:200]
    return f"{type(error).__name__}: {text}" if text else type(error).__name__
