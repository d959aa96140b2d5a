"""Push-to-talk on ``dms face``: "let's play bingo", synthesised with espeak-ng, said into
Chromium's fake microphone, recorded by the page, transcribed by pocketsphinx on the face's
side and sent as ``perception/speech``: the daemon starts bingo and the page deals the card.
"""

from __future__ import annotations

import shutil
import subprocess
import wave
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from dms.face.voice import unavailable
from tests.integration.harness import Collector
from tests.integration.test_face import Face, running_face
from tests.integration.viewer_harness import CHROMIUM, CHROMIUM_ARGS, browser_missing

PHRASE = "let's play bingo"


def _missing() -> str | None:
    if shutil.which("espeak-ng") is None:
        return "espeak-ng is not installed (apt-get install espeak-ng)"
    return unavailable() or browser_missing()


pytestmark = [
    pytest.mark.integration,
    pytest.mark.skipif(_missing() is not None, reason=str(_missing())),
]


def spoken(tmp: Path, text: str) -> tuple[Path, float]:
    """``text`` said by espeak-ng (a male US voice, slowly, as to a robot) with a second
    of silence after it: the WAV file and its length in seconds."""
    raw, padded = tmp / "raw.wav", tmp / "said.wav"
    subprocess.run(["espeak-ng", "-v", "en-us+m1", "-s", "110", "-w", str(raw), text], check=True)
    with wave.open(str(raw)) as source:
        params, frames = source.getparams(), source.readframes(source.getnframes())
    silence = b"\0" * (params.framerate * params.sampwidth * params.nchannels)
    with wave.open(str(padded), "wb") as out:
        out.setparams(params)
        out.writeframes(frames + silence)
    return padded, (len(frames) + len(silence)) / (params.framerate * params.sampwidth)


@pytest.fixture
def face(tmp_path: Path) -> Iterator[Face]:
    with running_face(tmp_path) as running:
        yield running


def test_a_recording_sent_to_the_face_is_heard_and_sent_with_its_confidence(
    face: Face, tmp_path: Path
) -> None:
    wav, _seconds = spoken(tmp_path, PHRASE)
    speech = Collector(face.session, "robots/mini/perception/speech")
    status, heard = face.call("/api/voice", wav.read_bytes(), {"Content-Type": "audio/wav"})
    assert status == 200, heard
    assert "bingo" in heard["text"] and heard["sent"] is True
    sent = speech.wait_for(lambda m: True)
    assert sent == {"text": heard["text"], "confidence": heard["confidence"]}
    assert 0.5 <= sent["confidence"] <= 1.0  # over the daemon's min_speech_confidence


def test_silence_is_heard_as_nothing_and_nothing_is_sent(face: Face, tmp_path: Path) -> None:
    quiet = tmp_path / "quiet.wav"
    with wave.open(str(quiet), "wb") as out:
        out.setnchannels(1)
        out.setsampwidth(2)
        out.setframerate(16_000)
        out.writeframes(b"\0" * 32_000)
    speech = Collector(face.session, "robots/mini/perception/speech")
    status, heard = face.call("/api/voice", quiet.read_bytes(), {"Content-Type": "audio/wav"})
    assert status == 200 and heard == {"text": "", "confidence": 0.0, "sent": False}
    face.call("/api/say", {"text": "marker"})  # what reaches the bus next is the marker
    assert speech.wait_for(lambda m: True) == {"text": "marker", "confidence": 1.0}


def test_lets_play_bingo_said_into_the_microphone_starts_bingo(face: Face, tmp_path: Path) -> None:
    from playwright.sync_api import sync_playwright

    wav, seconds = spoken(tmp_path, PHRASE)
    fake_microphone = [
        "--use-fake-ui-for-media-stream",
        "--use-fake-device-for-media-stream",
        f"--use-file-for-fake-audio-capture={wav}",
    ]
    decisions = Collector(face.session, "robots/mini/dms/decision")
    speech = Collector(face.session, "robots/mini/perception/speech")
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(
            executable_path=str(CHROMIUM), args=[*CHROMIUM_ARGS, *fake_microphone]
        )
        try:
            context = browser.new_context(
                viewport={"width": 1366, "height": 800}, permissions=["microphone"]
            )
            page: Any = context.new_page()
            errors: list[str] = []
            page.on("pageerror", lambda error: errors.append(str(error)))
            page.set_default_timeout(30_000)
            page.goto(face.url)
            page.wait_for_selector("body[data-ready='1']")
            status, _ = face.call("/api/here", {"user_id": "bea", "consent": True})
            assert status == 200
            decisions.wait_for(lambda d: d["activity"] == "menu", timeout=30)
            page.wait_for_selector("button[data-choice='bingo']")

            page.click("#talk-button")  # a tap: it listens until the next tap
            page.wait_for_selector("#talk-button.recording")
            page.wait_for_function(f"window.face.recorded > {seconds + 0.5}")
            page.click("#talk-button")
            page.wait_for_function("document.getElementById('heard').textContent.includes('bingo')")
            said = speech.wait_for(lambda m: "bingo" in m["text"])
            assert said["confidence"] >= 0.5, said
            started = decisions.wait_for(
                lambda d: d["action"] == "start" and d["activity"] == "bingo", timeout=30
            )
            assert started["chosen_by"] == "user"
            page.wait_for_selector(".card div:nth-child(9)", timeout=60_000)
            assert page.locator(".card div").count() == 9
            assert page.locator("button[data-choice='bingo']").inner_text() == "BINGO!"
            assert not errors, errors
        finally:
            browser.close()
