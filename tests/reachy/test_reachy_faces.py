"""The bridge's pure parts for ``--faces`` and posing by hand: the face's image position
as a point of ``perception/user``, presence, and the by-hand asks and their lease.

The face's mapping is checked against geometry worked by hand (the camera's axis, a
turned head, the image's sides) and against the daemon's own ``perception/user`` model.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "reachy"))

from dms_reachy import by_hand, faces
from dms_reachy.body import HEAD_ORIGIN_Z_M

from dms.kernel.messages import UserPerception

CAMERA = faces.LITE_CAMERA
ON_AXIS = (2 * CAMERA.cx / (CAMERA.width - 1) - 1, 2 * CAMERA.cy / (CAMERA.height - 1) - 1)
"""The image position of the principal point: a face there is on the camera's axis."""
LENS = (0.0437, 0.0, 0.0512)
"""The camera's place on the head (the SDK's head-to-camera transform)."""


def head_turned(yaw: float = 0.0, pitch: float = 0.0) -> list[list[float]]:
    """A head pose: yaw about z, then pitch about y (positive looks down), no offset."""
    cy, sy, cp, sp = math.cos(yaw), math.sin(yaw), math.cos(pitch), math.sin(pitch)
    return [
        [cy * cp, -sy, cy * sp, 0.0],
        [sy * cp, cy, sy * sp, 0.0],
        [-sp, 0.0, cp, 0.0],
        [0.0, 0.0, 0.0, 1.0],
    ]


def test_a_face_on_the_camera_s_axis_is_straight_ahead_at_the_assumed_distance() -> None:
    point = faces.face_position(*ON_AXIS, head_turned())
    assert point is not None
    want = (LENS[0] + faces.FACE_DISTANCE_M, 0.0, LENS[2] + HEAD_ORIGIN_Z_M)
    assert point == pytest.approx(want, abs=1e-6)


def test_a_head_turned_left_places_the_face_on_the_left() -> None:
    point = faces.face_position(*ON_AXIS, head_turned(yaw=math.pi / 2))
    assert point is not None
    want = (0.0, LENS[0] + faces.FACE_DISTANCE_M, LENS[2] + HEAD_ORIGIN_Z_M)
    assert point == pytest.approx(want, abs=1e-6)


def test_the_image_s_right_is_the_robot_s_right_and_its_top_is_up() -> None:
    centre = faces.face_position(*ON_AXIS, head_turned())
    right = faces.face_position(0.8, ON_AXIS[1], head_turned())
    top = faces.face_position(ON_AXIS[0], -0.8, head_turned())
    assert centre is not None and right is not None and top is not None
    assert right[1] < centre[1] - 0.2  # y is left: a face on the image's right is at -y
    assert top[2] > centre[2] + 0.2


@given(
    x=st.floats(-1, 1),
    y=st.floats(-1, 1),
    yaw=st.floats(-1.5, 1.5),
    pitch=st.floats(-0.6, 0.6),
    distance=st.floats(0.3, 3.0),
)
def test_the_face_is_always_the_assumed_distance_from_the_lens(
    x: float, y: float, yaw: float, pitch: float, distance: float
) -> None:
    head = head_turned(yaw, pitch)
    point = faces.face_position(x, y, head, distance_m=distance)
    assert point is not None
    lens = [sum(head[r][c] * LENS[c] for c in range(3)) for r in range(3)]
    lens[2] += HEAD_ORIGIN_Z_M
    assert math.dist(point, lens) == pytest.approx(distance, rel=1e-9)


@pytest.mark.parametrize("x, y", [(1.5, 0.0), (0.0, -1.01), (math.nan, 0.0), (0.0, math.inf)])
def test_a_position_outside_the_image_is_no_face(x: float, y: float) -> None:
    assert faces.face_position(x, y, head_turned()) is None


def test_presence_holds_through_a_short_loss_and_ends_after_it() -> None:
    presence = faces.Presence(lost_s=1.5)
    assert presence.user(None, now=0.0) == {"present": False}
    seen = presence.user((0.8, 0.1, 0.3), now=1.0)
    assert seen["present"] is True and seen["user_id"] is None
    assert seen["face"] == {"position": {"x": 0.8, "y": 0.1, "z": 0.3}}
    assert presence.user(None, now=2.4) == seen  # a blink of the detector: still there
    assert presence.user(None, now=2.5) == {"present": False}
    assert presence.user(None, now=9.0) == {"present": False}


def test_the_messages_are_the_daemon_s_perception_user() -> None:
    presence = faces.Presence()
    point = faces.face_position(0.1, -0.2, head_turned(0.3, 0.1))
    for message in (presence.user(point, 0.0), presence.user(None, 5.0)):
        parsed = UserPerception.model_validate(message)
        assert parsed.present is (message["present"] is True)
    assert UserPerception.model_validate(presence.user(point, 6.0)).face is not None


def test_an_ask_to_pose_by_hand_is_read_or_refused_with_its_reason() -> None:
    assert by_hand.parse(None) == by_hand.Ask(None)
    assert by_hand.parse(b'{"on": true, "lease_s": 5}') == by_hand.Ask(True, 5.0)
    assert by_hand.parse(b'{"on": false}') == by_hand.Ask(False, by_hand.DEFAULT_LEASE_S)
    refusals = {
        b"nope": "not JSON",
        b"[1]": "not a JSON object",
        b'{"on": "yes"}': "on: true or false",
        b'{"on": true, "lease_s": 0}': "lease_s",
        b'{"on": true, "lease_s": 1e9}': "lease_s",
        b'{"on": true, "lease_s": true}': "lease_s",
        b'{"on": true, "lease_s": NaN}': "lease_s",
        b"{" + b" " * 2000 + b"}": "more than",
    }
    for raw, reason in refusals.items():
        with pytest.raises(by_hand.BadAsk, match=reason):
            by_hand.parse(raw)


def test_the_lease_ends_unless_renewed_and_off_ends_it_at_once() -> None:
    lease = by_hand.Lease()
    assert not lease.wanted(0.0)
    lease.take(by_hand.Ask(True, 10.0), now=0.0)
    assert lease.wanted(9.9) and lease.left(9.9) == pytest.approx(0.1)
    lease.take(by_hand.Ask(True, 10.0), now=9.0)  # renewed
    assert lease.wanted(18.9)
    assert not lease.wanted(19.0) and lease.left(19.0) == 0.0
    lease.take(by_hand.Ask(True, 10.0), now=20.0)
    lease.take(by_hand.Ask(None), now=21.0)  # a question leaves it as it is
    assert lease.wanted(21.0)
    lease.take(by_hand.Ask(False), now=22.0)
    assert not lease.wanted(22.0)
