"""The Reachy Mini bridge's pure parts: the mapping, the gestures and the mixer.

``dms_reachy`` lives in its own environment, but these modules need nothing of the SDK
or of Zenoh, so they are tested here, beside the daemon's repertoire they must cover.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "reachy"))

from dms_reachy import body, commands, gestures
from dms_reachy.body import Posture
from dms_reachy.motion import REST, Mixer
from dms_reachy.speech import Voice, words_seconds

from dms.kernel import repertoire
from sim.robot import MOTION_SECONDS


def test_every_gesture_and_led_pattern_of_the_repertoire_has_a_movement() -> None:
    assert [g for g in repertoire.GESTURES if not gestures.known(g)] == []
    assert set(repertoire.LED_PATTERNS) <= set(gestures.PATTERNS)


def test_each_gesture_lasts_what_the_simulated_mini_s_does() -> None:
    for name, keyframes in gestures.GESTURES.items():
        assert gestures.length(keyframes) == MOTION_SECONDS[name], name


def test_a_gesture_starts_and_ends_where_the_robot_stands_and_passes_its_keyframes() -> None:
    nod = gestures.GESTURES["nod"]
    assert gestures.offsets_at(nod, 0.0) == {"pitch": 0.0}
    assert gestures.offsets_at(nod, 0.35 - 1e-9)["pitch"] == pytest.approx(0.30)
    assert gestures.offsets_at(nod, 1.5) == {}
    assert gestures.offsets_at(gestures.scaled(nod, 3.0), 0.7 - 1e-9)["pitch"] == pytest.approx(0.3)


@settings(max_examples=500, deadline=None)
@given(
    st.sampled_from(sorted(gestures.GESTURES)),
    st.floats(0.0, 4.0),
    st.floats(-3.0, 3.0),
    st.floats(-3.0, 3.0),
)
def test_every_posture_sent_is_within_reachy_mini_s_limits(
    name: str, at: float, body_yaw: float, yaw: float
) -> None:
    mixer = Mixer(stance=Posture(body_yaw=body_yaw, yaw=yaw), target=Posture(body_yaw, yaw))
    mixer.step(0.0)
    mixer.play("g", gestures.GESTURES[name], 0.0)
    posture, _ = mixer.step(at)
    assert abs(posture.body_yaw) <= body.BODY_YAW
    assert abs(posture.yaw - posture.body_yaw) <= body.YAW_DELTA + 1e-9
    assert abs(posture.pitch) <= body.HEAD_TILT and abs(posture.roll) <= body.HEAD_TILT
    assert abs(posture.left) <= body.ANTENNA and abs(posture.right) <= body.ANTENNA
    assert abs(posture.z) <= body.HEAD_Z


def test_an_aim_turns_at_the_contract_s_speed_and_is_done_once() -> None:
    mixer = Mixer()
    mixer.step(0.0)
    target = body.from_contract({"neck": 0.8}, mixer.target)
    assert mixer.aim("a", target, 0.0) is None
    seconds = 0.8 / (body.CONTRACT["hip"].speed + body.CONTRACT["neck"].speed)
    posture, done = mixer.step(seconds / 2)
    assert posture.yaw == pytest.approx(0.4) and done == []
    posture, done = mixer.step(seconds + 0.01)
    assert posture.yaw == pytest.approx(0.8) and done == ["a"]
    assert mixer.step(seconds + 0.1)[1] == []


def test_a_new_aim_replaces_the_one_under_way_and_a_stop_holds_where_it_got() -> None:
    mixer = Mixer()
    mixer.step(0.0)
    mixer.aim("a", Posture(yaw=1.0), 0.0)
    assert mixer.aim("b", Posture(yaw=-1.0), 0.1) == "a"
    assert mixer.stop("b", 0.2)
    held = mixer.step(0.2)[0].yaw
    assert mixer.step(1.0)[0].yaw == pytest.approx(held)
    assert not mixer.stop("b", 1.0)


def test_an_interrupted_gesture_eases_back_and_reports_nothing_more() -> None:
    mixer = Mixer()
    mixer.step(0.0)
    mixer.play("nod", gestures.GESTURES["nod"], 0.0)
    bowed = mixer.step(0.35)[0].pitch
    assert mixer.stop("nod", 0.35)
    assert 0.0 < mixer.step(0.45)[0].pitch < bowed
    posture, done = mixer.step(0.35 + 0.31)
    assert posture.pitch == pytest.approx(0.0) and done == []


def test_led_patterns_move_the_antennas_and_off_droops_them() -> None:
    mixer = Mixer()
    mixer.step(0.0)
    mixer.light(gestures.pattern_for("blue", "pulse"), 0.0)
    assert mixer.step(0.25)[0].left == pytest.approx(REST.left + 0.3)
    mixer.light(gestures.pattern_for("off", "pulse"), 1.0)
    assert mixer.step(1.25)[0].left == pytest.approx(REST.left + gestures.DROOP)


def test_the_contract_s_joints_map_to_reachy_and_back() -> None:
    posture = body.from_contract({"hip": 0.3, "neck": 0.2, "head": 0.1, "left_arm": 2.6}, REST)
    assert (posture.body_yaw, posture.yaw, posture.pitch) == pytest.approx((0.3, 0.5, 0.1))
    assert posture.left == pytest.approx(body.ANTENNA)
    assert body.to_contract(posture.body_yaw, posture.yaw, posture.pitch) == {
        "hip": 0.3,
        "neck": 0.2,
        "head": 0.1,
    }
    clamped = body.from_contract({"neck": 5.0, "head": -5.0}, REST)
    assert clamped.yaw == body.CONTRACT["neck"].high and clamped.pitch == -0.45


def test_a_point_in_the_dms_base_frame_is_looked_at_from_reachy_s_head() -> None:
    assert body.aim_at(0.5, 0.0, body.HEAD_ORIGIN_Z_M, 0.0) == pytest.approx((0.0, 0.0))
    yaw, pitch = body.aim_at(0.5, 0.5, body.HEAD_ORIGIN_Z_M + 0.5 * math.sqrt(2), 0.0)
    assert yaw == pytest.approx(math.pi / 4) and pitch == pytest.approx(-math.pi / 4)


@pytest.mark.parametrize(
    ("raw", "reason"),
    [
        (b"{", "not JSON"),
        (b"[]", "not a JSON object"),
        (b'{"id": "", "channel": "motion", "action": "gesture"}', "id must be"),
        (b'{"id": "c", "channel": "arm", "action": "x"}', "channel 'arm'"),
        (b'{"id": "c", "channel": "led", "action": "set", "args": []}', "args must be"),
        (b" " * (commands.MAX_PAYLOAD + 1), "more than"),
    ],
)
def test_a_command_it_cannot_read_is_refused_with_the_reason(raw: bytes, reason: str) -> None:
    with pytest.raises(commands.BadCommand, match=reason):
        commands.parse(raw)


def test_aim_arguments_are_read_within_the_contract_s_bounds() -> None:
    args = {"joints": {"neck": 0.2, "head": "x", "hip": float("nan")}, "position": {"x": 1}}
    assert commands.joints_of(args) == {"neck": 0.2}
    assert commands.position_of(args) is None
    assert commands.position_of({"position": {"x": 1, "y": 0, "z": 0.4}}) == (1.0, 0.0, 0.4)
    assert commands.seconds_of(1e9, 30.0, 3600.0) == 3600.0


def test_espeak_ng_speaks_a_sentence_into_a_wav_file_of_its_length() -> None:
    voice = Voice()
    assert voice.available, "apt-get install espeak-ng (docs/reachy.md)"
    try:
        short, short_s = voice.synthesize("Hello.", 150, "en")
        long, long_s = voice.synthesize("Let's play a quiz, my friend! " * 3, 150, "en")
        assert short.read_bytes()[:4] == b"RIFF" and long.is_file()
        assert 0.2 < short_s < long_s < 15.0
        with pytest.raises(OSError, match="espeak-ng"):
            voice.synthesize("Hello.", 150, "nolanguage")
    finally:
        voice.close()
    assert not short.exists()  # its folder goes with it


def test_printed_speech_is_timed_at_the_speaking_rate() -> None:
    assert words_seconds("one two three", None) == pytest.approx(0.3 + 60 * 3 / 150)
    assert words_seconds("one two three", 300) == pytest.approx(0.3 + 60 * 3 / 300)
    assert words_seconds("one two three", 10_000) == words_seconds("one two three", None)
