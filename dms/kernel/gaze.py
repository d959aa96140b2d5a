"""Gaze and pointing: the joint angles that face a frame, point an arm at it, and the
attend behavior that keeps the gaze on a person.

:func:`aim` turns a frame into hip, neck and head angles within the joints' limits
(the neck pans first; the hip turns only for what the neck cannot reach).
:class:`Attention` is the attend behavior's model: it keeps the gaze on a frame (the
user's face) without jitter (a dead band, at most a few gaze shifts per second), holds
the last gaze while the frame is briefly stale, and returns to neutral once it has been
stale for ``neutral_after_s``. :func:`point` turns the hip and raises one arm toward a
frame (an arm moves only up and down, so the hip gives the direction). Pure: every
call takes ``now`` and returns the targets to send, or None when nothing should move.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from datetime import datetime

from dms.kernel.body import (
    HEAD_HEIGHT_M,
    HIP_HEIGHT_M,
    JOINTS,
    NECK_HEIGHT_M,
    NEUTRAL,
    SHOULDER_HEIGHT_M,
)
from dms.kernel.frames import FrameStore, Located, UnknownFrame

EYE_HEIGHT_M = HIP_HEIGHT_M + NECK_HEIGHT_M + HEAD_HEIGHT_M
GAZE_JOINTS = ("hip", "neck", "head")


def aim(located: Located, hip_now: float = 0.0) -> dict[str, float]:
    """Hip, neck and head angles that point the head at ``located`` (in the base frame),
    turning the hip from ``hip_now`` only when the neck alone cannot reach."""
    x, y, z = located.position
    yaw = math.atan2(y, x) if (x or y) else hip_now
    neck = JOINTS["neck"].clamp(yaw - hip_now)
    hip = hip_now
    if abs(yaw - hip_now - neck) > 1e-9:
        hip = JOINTS["hip"].clamp(yaw - neck)
        neck = JOINTS["neck"].clamp(yaw - hip)
    tilt = JOINTS["head"].clamp(math.atan2(EYE_HEIGHT_M - z, math.hypot(x, y)))
    return {"hip": hip, "neck": neck, "head": tilt}


def turn_toward(located: Located) -> dict[str, float]:
    """The hip angle that turns the body toward ``located`` (in the base frame): a
    gesture made toward someone."""
    x, y, _ = located.position
    return {"hip": JOINTS["hip"].clamp(math.atan2(y, x)) if (x or y) else 0.0}


def point(located: Located, arm: str = "right_arm") -> dict[str, float]:
    """Hip and ``arm`` angles that point the arm at ``located`` (in the base frame)."""
    x, y, z = located.position
    hip = JOINTS["hip"].clamp(math.atan2(y, x)) if (x or y) else 0.0
    drop = z - (HIP_HEIGHT_M + SHOULDER_HEIGHT_M)
    raised = JOINTS[arm].clamp(math.atan2(math.hypot(x, y), -drop))
    return {"hip": hip, arm: raised}


@dataclass(frozen=True, slots=True)
class AttentionSettings:
    """How the robot keeps its gaze on a person: what reads as natural, not robotic."""

    dead_band_rad: float = 0.06
    """A move smaller than this (about 3.5 degrees) is not made: no jitter."""
    max_shifts_per_s: float = 3.0
    """At most this many gaze shifts a second."""
    neutral_after_s: float = 3.0
    """The frame stale this long: look ahead again (the person is no longer seen)."""


class Attention:
    """Keeps the gaze on ``frame`` (``attend``); one instance per attending activity."""

    def __init__(self, frame: str, settings: AttentionSettings | None = None) -> None:
        self.frame = frame
        self.settings = settings or AttentionSettings()
        self._sent: dict[str, float] | None = None
        self._sent_at: datetime | None = None
        self.shifts = 0
        self.located: Located | None = None
        """Where the frame was at the last update that looked it up (None: unknown)."""
        self._settled: tuple[int, float, datetime] | None = None
        """(the store's moves, the hip, live until): the last full update found nothing
        to send for a live frame; while these hold, nothing can have changed."""

    @property
    def sent(self) -> Mapping[str, float] | None:
        """The last targets sent (None: none yet)."""
        return self._sent

    def update(
        self, frames: FrameStore, now: datetime, hip_now: float = 0.0
    ) -> dict[str, float] | None:
        """The gaze targets to send now, or None (nothing to change, or too soon)."""
        settled = self._settled
        if settled is not None and settled[:2] == (frames.moves, hip_now) and now <= settled[2]:
            return None  # most ticks: the face has not moved, nor gone stale
        self._settled = None
        try:
            located: Located | None = frames.lookup(self.frame, now)
        except UnknownFrame:
            located = None
        self.located = located
        if located is None or (not located.live and located.age_s > self.settings.neutral_after_s):
            wanted = {name: NEUTRAL[name] for name in GAZE_JOINTS}
        elif not located.live:
            return None  # briefly unseen: hold the gaze where the person was
        else:
            wanted = aim(located, hip_now)
        previous = self._sent
        if previous is not None:
            moved = max(abs(wanted[name] - previous[name]) for name in GAZE_JOINTS)
            if moved < self.settings.dead_band_rad:
                if located is not None and located.live:
                    until = frames.live_until(self.frame)
                    if until is not None:
                        self._settled = (frames.moves, hip_now, until)
                return None
            if self._sent_at is not None:
                since = (now - self._sent_at).total_seconds()
                if since < 1.0 / self.settings.max_shifts_per_s:
                    return None
        self._sent, self._sent_at = wanted, now
        self.shifts += 1
        return dict(wanted)
