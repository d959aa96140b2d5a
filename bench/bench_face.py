"""The latency a person in front of ``dms face`` feels: a tap to the robot's answer, and
the end of an utterance to the daemon's decision.

Starts a daemon (``dms run``: real Zenoh on 127.0.0.1, SQLite, the simulated Mini; the
person always chooses, through a ``ChooseMode`` rule) and ``dms face`` beside it, and
opens the page in Debian's Chromium (Playwright) with a fake microphone playing "let's
play bingo" (espeak-ng). A person arrives; then, each time the menu is on the tablet:

- ``tap``: a tap on an activity, to the robot's answer arriving on the page (its next
  utterance, "Great, let's go!"), both on the page's clock;
- ``speech``: the end of push-to-talk (the tap that stops the recording) to the robot's
  answer (the menu's "Great, let's go!") and to the ``start`` decision of bingo (which
  follows that sentence) arriving on the page: the recording sent, transcribed by
  pocketsphinx, published as ``perception/speech`` and decided on. ``transcribe_ms`` is
  the server's share (the POST's round trip). An utterance heard without "bingo", or
  under the daemon's confidence threshold, is counted as ``misheard`` and decides
  nothing.

Between trials a ``cancel`` request from another process brings the menu back. Prints one
JSON object with p50 and p95 of each, in milliseconds.

    .venv/bin/python bench/bench_face.py [--quick]
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from dms.face.voice import unavailable
from tests.integration.harness import Collector, put
from tests.integration.test_face import Face, running_face
from tests.integration.test_face_voice import PHRASE, spoken
from tests.integration.viewer_harness import CHROMIUM, CHROMIUM_ARGS

TAPS = 20
UTTERANCES = 10
WAIT_MS = 60_000
MIN_CONFIDENCE = 0.5
"""The daemon's default ``min_speech_confidence``: an utterance under it is not understood."""
TAPPED = "jokes"
"""The activity tapped: it has no closing sentence, so its cancel leaves the voice free."""


def percentiles(values: list[float]) -> dict[str, float]:
    return {
        "p50": round(float(np.percentile(values, 50)), 1),
        "p95": round(float(np.percentile(values, 95)), 1),
        "max": round(max(values), 1),
    }


def menu_again(face: Face, page: Any, decisions: Collector, activity: str, since: int) -> None:
    """Once ``activity`` started (after decision ``since``), cancel it from another program
    and wait for the menu on the tablet."""
    decisions.wait_for(
        lambda d: d["action"] == "start" and d["activity"] == activity, timeout=60, start=since
    )
    mark = decisions.mark()
    put(face.session, "request", {"action": "cancel", "activity": activity, "by": "bench"})
    decisions.wait_for(
        lambda d: d["action"] == "start" and d["activity"] == "menu", timeout=60, start=mark
    )
    page.wait_for_selector(f"button[data-choice='{TAPPED}']:not([disabled])")


def after(page: Any, start: int, kind: str, text: str = "") -> dict[str, Any]:
    """The first entry of the page's log from ``start`` on of ``kind`` holding ``text``."""
    page.wait_for_function(
        "([start, kind, text]) => window.face.log.slice(start).some("
        "e => e.kind === kind && e.text.includes(text))",
        arg=[start, kind, text],
        timeout=WAIT_MS,
    )
    entries: list[dict[str, Any]] = page.evaluate("start => window.face.log.slice(start)", start)
    return next(e for e in entries if e["kind"] == kind and text in e["text"])


def tap_once(face: Face, page: Any, decisions: Collector) -> float:
    start, since = page.evaluate("window.face.log.length"), decisions.mark()
    page.click(f"button[data-choice='{TAPPED}']")
    tapped = after(page, start, "tap", TAPPED)
    answered = after(page, start, "say", "Great")  # the menu's "Great, let's go!"
    menu_again(face, page, decisions, TAPPED, since)
    return float(answered["t"] - tapped["t"])


def speak_once(
    face: Face, page: Any, decisions: Collector, seconds: float
) -> tuple[float | None, float | None, float]:
    """Push-to-talk once: speech end to the robot's answer and to the decision (None
    when misheard), and the transcription's round trip."""
    page.click("#talk-button")
    page.wait_for_selector("#talk-button.recording")
    page.wait_for_function(f"window.face.recorded > {seconds + 0.5}", timeout=WAIT_MS)
    start, since = page.evaluate("window.face.log.length"), decisions.mark()
    with page.expect_response(lambda r: "/api/voice" in r.url) as posted:
        began = time.perf_counter()
        page.click("#talk-button")
    heard = posted.value.json()
    transcribe_ms = (time.perf_counter() - began) * 1000
    if "bingo" not in heard.get("text", "") or heard.get("confidence", 0) < MIN_CONFIDENCE:
        return None, None, transcribe_ms  # misheard: the daemon decides nothing
    ended = after(page, start, "speech-end")
    answered = after(page, start, "say", "Great")
    decided = after(page, start, "decision", "start bingo")
    menu_again(face, page, decisions, "bingo", since)
    return float(answered["t"] - ended["t"]), float(decided["t"] - ended["t"]), transcribe_ms


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="3 taps and 2 utterances (smoke)")
    quick = parser.parse_args().quick
    taps, utterances = (3, 2) if quick else (TAPS, UTTERANCES)
    voice = unavailable() or (None if shutil.which("espeak-ng") else "no espeak-ng")
    from playwright.sync_api import sync_playwright

    tap_ms: list[float] = []
    answer_ms: list[float] = []
    speech_ms: list[float] = []
    transcribe_ms: list[float] = []
    misheard = 0
    with tempfile.TemporaryDirectory() as tmp, running_face(Path(tmp)) as face:
        wav, seconds = spoken(Path(tmp), PHRASE) if voice is None else (None, 0.0)
        microphone = (
            [
                "--use-fake-ui-for-media-stream",
                "--use-fake-device-for-media-stream",
                f"--use-file-for-fake-audio-capture={wav}",
            ]
            if wav
            else []
        )
        decisions = Collector(face.session, "robots/mini/dms/decision")
        with sync_playwright() as playwright:
            browser = playwright.chromium.launch(
                executable_path=str(CHROMIUM), args=[*CHROMIUM_ARGS, *microphone]
            )
            try:
                context = browser.new_context(
                    viewport={"width": 1366, "height": 800}, permissions=["microphone"]
                )
                page = context.new_page()
                page.set_default_timeout(WAIT_MS)
                page.goto(face.url)
                page.wait_for_selector("body[data-ready='1']")
                face.call("/api/here", {"user_id": "bench", "consent": True})
                page.wait_for_selector(f"button[data-choice='{TAPPED}']")
                for _ in range(taps):
                    tap_ms.append(tap_once(face, page, decisions))
                for _ in range(utterances if wav else 0):
                    answered, decided, transcribed = speak_once(face, page, decisions, seconds)
                    transcribe_ms.append(transcribed)
                    if answered is None or decided is None:
                        misheard += 1
                    else:
                        answer_ms.append(answered)
                        speech_ms.append(decided)
            finally:
                browser.close()
    result: dict[str, Any] = {
        "quick": quick,
        "taps": len(tap_ms),
        "tap_to_answer_ms": percentiles(tap_ms),
        "utterances": len(transcribe_ms),
        "misheard": misheard,
    }
    if speech_ms:
        result["speech_end_to_answer_ms"] = percentiles(answer_ms)
        result["speech_end_to_decision_ms"] = percentiles(speech_ms)
    if transcribe_ms:
        result["transcribe_ms"] = percentiles(transcribe_ms)
    else:
        result["voice"] = f"not measured: {voice}"
    print(json.dumps(result))


if __name__ == "__main__":
    main()
