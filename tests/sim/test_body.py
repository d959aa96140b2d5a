"""The simulated Mini's body: joints move at their speed, within
their limits, toward the targets a gaze sets; the head follows a face that moves."""

from __future__ import annotations

import itertools
import math
from datetime import UTC, datetime, timedelta

import pytest

from dms.kernel.body import JOINTS
from dms.kernel.frames import FrameStore, pose
from dms.kernel.gaze import EYE_HEIGHT_M, Attention
from sim.body import SimBody

T0 = datetime(2026, 11, 24, 10, 0, tzinfo=UTC)


def test_a_joint_moves_at_its_speed_and_stops_at_its_target() -> None:
    body = SimBody(T0)
    body.aim({"neck": 0.8}, T0)
    speed = JOINTS["neck"].speed
    half = body.advance(T0 + timedelta(seconds=0.25))
    assert half["neck"] == pytest.approx(speed * 0.25)
    assert body.moving
    done = body.advance(T0 + timedelta(seconds=5))
    assert done["neck"] == pytest.approx(0.8) and not body.moving


def test_targets_beyond_the_limits_are_clamped_and_unknown_joints_refused() -> None:
    body = SimBody(T0)
    body.aim({"head": 3.0, "hip": -9.0}, T0)
    end = body.advance(T0 + timedelta(seconds=60))
    assert end["head"] == JOINTS["head"].high and end["hip"] == JOINTS["hip"].low
    with pytest.raises(KeyError):
        body.aim({"tail": 1.0}, T0)


def test_the_head_follows_a_face_moving_from_left_to_right_within_its_speed() -> None:
    """The user leans from the robot's left to its right over 4 s, ticked at 2 Hz."""
    frames, body = FrameStore(), SimBody(T0)
    attention = Attention("face:ann")
    neck: list[float] = []
    for tick in range(15):  # 4 s moving, then 3 s still
        now = T0 + timedelta(seconds=tick * 0.5)
        y = max(-0.6, 0.6 - 0.3 * tick * 0.5)  # +0.6 m (left) to -0.6 m (right)
        frames.set("face:ann", pose((1.0, y, EYE_HEIGHT_M)), stamp=now, stale_after_s=1.0)
        targets = attention.update(frames, now, hip_now=body.positions["hip"])
        if targets is not None:
            body.aim(targets, now)
        neck.append(body.advance(now)["neck"])
    assert neck[-1] == pytest.approx(math.atan2(-0.6, 1.0), abs=0.07)  # the dead band
    steps = [abs(b - a) for a, b in itertools.pairwise(neck)]
    assert max(steps) <= JOINTS["neck"].speed * 0.5 + 1e-9, "never faster than the motor"
    assert max(neck[:3]) > 0.3 and neck[-1] < -0.3, "it turned from left to right"


def test_a_stale_face_sends_the_head_back_to_neutral_after_the_configured_time() -> None:
    frames, body = FrameStore(), SimBody(T0)
    attention = Attention("face:ann")
    frames.set("face:ann", pose((1.0, 0.8, EYE_HEIGHT_M)), stamp=T0, stale_after_s=1.0)
    body.aim(attention.update(frames, T0) or {}, T0)
    assert body.advance(T0 + timedelta(seconds=2))["neck"] > 0.5
    for tick in range(4, 12):  # no new face: held at first, then neutral after 3 s stale
        now = T0 + timedelta(seconds=tick * 0.5)
        targets = attention.update(frames, now)
        if targets is not None:
            body.aim(targets, now)
        body.advance(now)
    assert body.advance(T0 + timedelta(seconds=8))["neck"] == pytest.approx(0.0)
