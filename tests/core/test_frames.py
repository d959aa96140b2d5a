"""The frame store, the Mini's body frames, gaze and pointing.

Property tests (hypothesis) of composition and inversion, and of staleness; then the
geometry a person would check by eye: a face on the left makes the robot pan left, a
face too far to the side turns the hip, a face below the eyes tilts the head down.
"""

from __future__ import annotations

import math
from datetime import UTC, datetime, timedelta

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dms.kernel.body import HEAD, JOINTS, NECK, body_frames
from dms.kernel.frames import BASE, FrameStore, UnknownFrame, invert, pose
from dms.kernel.gaze import EYE_HEIGHT_M, Attention, AttentionSettings, aim, point

T0 = datetime(2026, 11, 24, 10, 0, tzinfo=UTC)

coordinate = st.floats(-3.0, 3.0, allow_nan=False)
angle = st.floats(-math.pi, math.pi, allow_nan=False)
xyz = st.tuples(coordinate, coordinate, coordinate)
rpy = st.tuples(angle, angle, angle)


@settings(max_examples=200, deadline=None)
@given(xyz, rpy)
def test_a_transform_composed_with_its_inverse_is_the_identity(t: tuple, r: tuple) -> None:
    matrix = pose(t, rpy=r)
    assert np.allclose(matrix @ invert(matrix), np.eye(4), atol=1e-9)
    assert np.allclose(invert(invert(matrix)), matrix, atol=1e-9)


@settings(max_examples=200, deadline=None)
@given(xyz, rpy, xyz, rpy, xyz)
def test_lookups_compose_and_invert(
    ta: tuple, ra: tuple, tb: tuple, rb: tuple, point_in_b: tuple
) -> None:
    """b under a under base: b in base is a @ b; a in b is the inverse of b in a."""
    frames = FrameStore()
    frames.set("a", pose(ta, rpy=ra))
    frames.set("b", pose(tb, rpy=rb), parent="a")
    b_in_base = frames.lookup("b", T0).matrix
    assert np.allclose(b_in_base, pose(ta, rpy=ra) @ pose(tb, rpy=rb), atol=1e-9)
    a_in_b = frames.lookup("a", T0, reference="b").matrix
    b_in_a = frames.lookup("b", T0, reference="a").matrix
    assert np.allclose(a_in_b @ b_in_a, np.eye(4), atol=1e-9)
    # a point expressed in b, taken to base and back, is where it was
    p = np.array([*point_in_b, 1.0])
    back = invert(b_in_base) @ (b_in_base @ p)
    assert np.allclose(back, p, atol=1e-9)


@settings(max_examples=100, deadline=None)
@given(st.floats(0.0, 60.0), st.floats(0.1, 10.0))
def test_a_perceived_frame_is_live_until_its_limit_then_last_known(
    age_s: float, stale_after_s: float
) -> None:
    frames = FrameStore()
    frames.set("face:ann", pose((1.0, 0.2, 0.4)), stamp=T0, stale_after_s=stale_after_s)
    frames.set("nose", pose((0.05, 0.0, 0.0)), parent="face:ann")  # a body-like child
    located = frames.lookup("nose", T0 + timedelta(seconds=age_s))
    assert located.age_s == pytest.approx(age_s, abs=1e-6)  # timedelta keeps microseconds
    assert located.live == (located.age_s <= stale_after_s)
    assert located.position == pytest.approx((1.05, 0.2, 0.4)), "the last known pose stays"


def test_body_frames_are_never_stale_and_unknown_frames_are_said() -> None:
    frames = FrameStore(body_frames({}))
    located = frames.lookup(HEAD, T0 + timedelta(days=365))
    assert located.live and located.age_s == 0.0
    with pytest.raises(UnknownFrame):
        frames.lookup("face:nobody", T0)
    with pytest.raises(ValueError, match="cycle"):
        frames.set(NECK, pose(), parent=HEAD)
    frames.set("object:cup", pose((0.3, 0.0, 0.0)), parent=HEAD)
    frames.forget(HEAD)
    assert HEAD not in frames and "object:cup" not in frames and NECK in frames


def test_the_head_frame_follows_the_joints() -> None:
    """Pan left 90 degrees: the camera, ahead of the head, is now on the robot's left."""
    frames = FrameStore(body_frames({"neck": math.pi / 2}))
    x, y, _ = frames.lookup(HEAD, T0).position
    assert x == pytest.approx(0.0, abs=1e-9) and y > 0.0
    frames = FrameStore(body_frames({"neck": 0.0, "head": 0.3}))
    ahead = frames.lookup(HEAD, T0).matrix[:3, 0]  # the camera's x axis in base
    assert ahead[2] < 0.0, "a positive tilt looks down"


def _face(frames: FrameStore, x: float, y: float, z: float, at: datetime = T0) -> None:
    frames.set("face:ann", pose((x, y, z)), stamp=at, stale_after_s=1.0)


def test_aim_pans_toward_a_face_and_tilts_to_its_height() -> None:
    frames = FrameStore()
    _face(frames, 0.8, 0.8, EYE_HEIGHT_M)  # 45 degrees to the left, at eye height
    angles = aim(frames.lookup("face:ann", T0))
    assert angles["neck"] == pytest.approx(math.pi / 4) and angles["hip"] == 0.0
    assert angles["head"] == pytest.approx(0.0, abs=1e-9)
    _face(frames, 0.6, 0.0, EYE_HEIGHT_M - 0.6)  # 45 degrees below
    assert aim(frames.lookup("face:ann", T0))["head"] == JOINTS["head"].high


def test_a_face_beyond_the_neck_turns_the_hip() -> None:
    frames = FrameStore()
    _face(frames, 0.0, -1.0, EYE_HEIGHT_M)  # straight right: -90 degrees
    angles = aim(frames.lookup("face:ann", T0))
    assert angles["neck"] == JOINTS["neck"].low
    assert angles["hip"] + angles["neck"] == pytest.approx(-math.pi / 2)


def test_point_raises_the_arm_toward_an_object_ahead() -> None:
    frames = FrameStore()
    frames.set("object:cup", pose((0.5, 0.0, 0.34)))  # ahead, at shoulder height
    angles = point(frames.lookup("object:cup", T0), "right_arm")
    assert angles["right_arm"] == pytest.approx(math.pi / 2) and angles["hip"] == 0.0


def test_attention_keeps_still_within_the_dead_band_and_shifts_at_most_three_times_a_second() -> (
    None
):
    frames = FrameStore()
    attention = Attention("face:ann", AttentionSettings(dead_band_rad=0.06, max_shifts_per_s=3))
    _face(frames, 1.0, 0.0, EYE_HEIGHT_M)
    assert attention.update(frames, T0) is not None
    _face(frames, 1.0, 0.03, EYE_HEIGHT_M, T0)  # 1.7 degrees: within the dead band
    assert attention.update(frames, T0 + timedelta(seconds=1)) is None
    shifts = 0
    for step in range(20):  # a face swaying a lot, ticked at 10 Hz for 2 s
        now = T0 + timedelta(seconds=1 + step / 10)
        _face(frames, 1.0, 0.5 if step % 2 else -0.5, EYE_HEIGHT_M, now)
        shifts += attention.update(frames, now) is not None
    assert 1 <= shifts <= 7, shifts


def test_attention_holds_a_briefly_lost_face_then_returns_to_neutral() -> None:
    frames = FrameStore()
    attention = Attention("face:ann", AttentionSettings(neutral_after_s=3.0))
    _face(frames, 1.0, 1.0, EYE_HEIGHT_M)
    looked = attention.update(frames, T0)
    assert looked is not None and looked["neck"] > 0.5
    assert attention.update(frames, T0 + timedelta(seconds=2)) is None, "held"
    back = attention.update(frames, T0 + timedelta(seconds=4))
    assert back == {"hip": 0.0, "neck": 0.0, "head": 0.0}
    assert attention.update(frames, T0 + timedelta(seconds=5)) is None, "once"


def test_attention_without_a_face_looks_ahead() -> None:
    attention = Attention("face:ann")
    assert attention.update(FrameStore(), T0) == {"hip": 0.0, "neck": 0.0, "head": 0.0}
    assert attention.update(FrameStore(), T0 + timedelta(seconds=1)) is None


def test_the_base_frame_cannot_be_moved() -> None:
    with pytest.raises(ValueError, match="root"):
        FrameStore().set(BASE, pose())
