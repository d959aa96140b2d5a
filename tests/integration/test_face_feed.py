"""The face's model of what the page shows, and its reading of recordings, without a
daemon: what the daemon's commands become, and what a malformed or oversized one does
(nothing, or a cut copy)."""

from __future__ import annotations

import io
import wave
from typing import Any

import numpy as np
import pytest

from dms.face.feed import CAPTIONS_KEPT, LISTENERS_MAX, MAX_CHOICES, MAX_TEXT, FaceFeed
from dms.face.voice import RATE, VoiceError, read_wav, voiced


def listening(feed: FaceFeed) -> list[tuple[str, dict[str, Any]]]:
    events: list[tuple[str, dict[str, Any]]] = []
    assert feed.attach(lambda name, data: events.append((name, data))) is not None
    return events


def test_each_channel_becomes_its_event_and_is_kept_for_a_page_opened_later() -> None:
    feed = FaceFeed("mini")
    events = listening(feed)
    feed.on_command(
        {"id": "1", "channel": "speech", "action": "say", "args": {"text": "Hi", "rate_wpm": 120}}
    )
    feed.on_command(
        {
            "id": "2",
            "channel": "screen",
            "action": "show",
            "args": {"text": "Pick", "choices": ["quiz", 3]},
        }
    )
    feed.on_command(
        {
            "id": "3",
            "channel": "led",
            "action": "set",
            "args": {"color": "blue", "pattern": "breathing"},
        }
    )
    feed.on_command(
        {
            "id": "4",
            "channel": "aim",
            "action": "look_at",
            "args": {"joints": {"neck": 0.5, "head": -0.2}},
        }
    )
    feed.on_command(
        {"id": "5", "channel": "aim", "action": "look_at", "args": {"frame": None, "joints": {}}}
    )
    assert [name for name, _ in events] == ["say", "screen", "led", "gaze", "gaze"]
    assert events[0][1] == {"id": "1", "text": "Hi", "rate_wpm": 120.0}
    assert events[1][1]["choices"] == ["quiz", "3"]
    assert events[3][1] == {"neck": 0.5, "head": -0.2}
    assert events[4][1] == {"neck": 0.0, "head": 0.0, "hip": 0.0}  # back to neutral
    later = feed.snapshot()
    assert later["said"][-1]["text"] == "Hi" and later["screen"]["text"] == "Pick"
    assert later["led"] == {"color": "blue", "pattern": "breathing"}


@pytest.mark.parametrize(
    "payload",
    [
        None,
        [],
        "say hello",
        {"channel": "speech", "action": "say", "args": "hello"},
        {"channel": "speech", "action": "say", "args": {"text": 42}},
        {"channel": "speech", "action": "say", "args": {"text": "   "}},
        {"channel": "aim", "action": "look_at", "args": {"joints": {"neck": "left"}}},
        {"channel": "aim", "action": "look_at", "args": {"joints": {"neck": float("nan")}}},
        {"channel": "media", "action": "play", "args": {}},
    ],
)
def test_a_malformed_or_foreign_command_changes_nothing(payload: Any) -> None:
    feed = FaceFeed("mini")
    events = listening(feed)
    before = feed.snapshot()
    feed.on_command(payload)
    assert events == [] and feed.snapshot() == before


def test_what_a_page_gets_is_bounded() -> None:
    feed = FaceFeed("mini")
    choices = [f"c{i}" * 200 for i in range(MAX_CHOICES + 10)]
    feed.on_command(
        {"channel": "screen", "action": "show", "args": {"text": "x" * 10_000, "choices": choices}}
    )
    screen = feed.snapshot()["screen"]
    assert len(screen["text"]) == MAX_TEXT and len(screen["choices"]) == MAX_CHOICES
    for n in range(CAPTIONS_KEPT + 5):
        feed.on_command({"channel": "speech", "action": "say", "args": {"text": f"line {n}"}})
    said = feed.snapshot()["said"]
    assert len(said) == CAPTIONS_KEPT and said[-1]["text"] == f"line {CAPTIONS_KEPT + 4}"
    for _ in range(LISTENERS_MAX):
        assert feed.attach(lambda name, data: None) is not None
    assert feed.attach(lambda name, data: None) is None  # one page too many


def test_state_events_come_only_when_the_user_or_the_activity_changes() -> None:
    feed = FaceFeed("mini")
    events = listening(feed)
    state = {"user": {"id": "ada"}, "activity": {"name": "quiz", "status": "running"}}
    feed.on_state(state)
    feed.on_state(state)
    feed.on_state({**state, "activity": None})
    assert [data["activity"] for _, data in events] == ["quiz", None]


def wav_bytes(samples: np.ndarray[Any, Any], rate: int, channels: int = 1) -> bytes:
    out = io.BytesIO()
    with wave.open(out, "wb") as w:
        w.setnchannels(channels)
        w.setsampwidth(2)
        w.setframerate(rate)
        w.writeframes(samples.astype("<i2").tobytes())
    return out.getvalue()


def test_a_48_khz_stereo_recording_is_read_as_16_khz_mono() -> None:
    seconds = 0.5
    t = np.arange(int(48_000 * seconds)) / 48_000
    tone = (8000 * np.sin(2 * np.pi * 440 * t)).astype(np.int16)
    stereo = np.column_stack([tone, tone]).reshape(-1)
    samples = read_wav(wav_bytes(stereo, 48_000, channels=2))
    assert len(samples) == int(RATE * seconds)
    assert 5000 < np.abs(samples).max() <= 8000  # the tone kept, averaged down


def test_silence_has_no_voiced_part_and_a_sound_keeps_its_margin() -> None:
    assert voiced(np.zeros(RATE, dtype=np.int16)) is None
    sound = np.zeros(3 * RATE, dtype=np.int16)
    sound[RATE : 2 * RATE] = (6000 * np.sin(np.arange(RATE) / 3)).astype(np.int16)
    kept = voiced(sound)
    assert kept is not None and 1.4 * RATE <= len(kept) <= 1.7 * RATE


@pytest.mark.parametrize(
    ("data", "named"),
    [
        (b"", "not a WAV"),
        (b"RIFF\x00\x00\x00\x00WAVEjunk", "not a WAV"),
        (wav_bytes(np.zeros(10, dtype=np.int16), 4_000), "8-96 kHz"),
        (wav_bytes(np.zeros(21 * 16_000, dtype=np.int16), 16_000), "longer than"),
    ],
)
def test_a_recording_that_cannot_be_read_says_why(data: bytes, named: str) -> None:
    with pytest.raises(VoiceError, match=named):
        read_wav(data)
