"""``dms face``'s page in Debian's Chromium, driven by Playwright as a person would, against
a real daemon: a new person arrives (and consents), types her name on the on-screen
keyboard, answers the opening question by tapping, picks the quiz from the menu, plays a
round by tapping an answer, touches the right shoulder and confirms the cancel, plays the
quiz again until she touches the left shoulder, rates it, and leaves; each step's
decision arrives, and the page shows what the robot says and shows. Saves docs/face.png.
"""

from __future__ import annotations

import csv
import io
import subprocess
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from tests.integration.harness import Collector, put
from tests.integration.test_face import Face, running_face
from tests.integration.viewer_harness import CHROMIUM, CHROMIUM_ARGS, browser_missing

SCREENSHOT = Path(__file__).resolve().parents[2] / "docs" / "face.png"
WAIT_MS = 30_000
DECISION_S = 40.0
"""A decision waits on the robot's speech (fast, but not instant) on a loaded machine."""

pytestmark = [
    pytest.mark.integration,
    pytest.mark.skipif(browser_missing() is not None, reason=str(browser_missing())),
]


@pytest.fixture
def face(tmp_path: Path) -> Iterator[Face]:
    with running_face(tmp_path, session_questions=2, serve_profiles=True) as running:
        yield running


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
        try:
            yield browser
        finally:
            browser.close()


@pytest.fixture
def page(face: Face, browser: Any) -> Iterator[Any]:
    page = browser.new_page(viewport={"width": 1366, "height": 800})
    errors: list[str] = []
    page.on("pageerror", lambda error: errors.append(str(error)))
    page.set_default_timeout(WAIT_MS)
    page.goto(face.url)
    page.wait_for_selector("body[data-ready='1']")
    yield page
    page.close()
    assert not errors, errors


def said(page: Any, words: str) -> None:
    """Wait until the caption (what the robot says now) holds ``words``."""
    page.wait_for_function(
        "words => document.getElementById('caption').textContent.includes(words)", arg=words
    )


def decided(
    decisions: Collector, start: int, match: Callable[[dict[str, Any]], bool]
) -> dict[str, Any]:
    return decisions.wait_for(match, timeout=DECISION_S, start=start)


def test_a_person_arrives_plays_the_quiz_rates_it_and_leaves(face: Face, page: Any) -> None:
    decisions = Collector(face.session, "robots/mini/dms/decision")
    screens = Collector(face.session, "robots/mini/perception/screen")
    users = Collector(face.session, "robots/mini/perception/user")
    assert page.inner_text("#who") == "Nobody is here"

    # someone new: her name on the on-screen keyboard, then the consent screen
    page.click("#new-person")
    for key in "ADA":
        page.click(f".keys button:text-is('{key}')")
    assert page.input_value(".typed") == "Ada"
    page.click(".send")
    consent = page.inner_text(".consent")
    assert "dms users erase ada" in consent and "your name" in consent
    assert not [m for m in users.messages if m["present"]]  # nothing recorded before consent
    mark = decisions.mark()
    page.click("#consent-yes")
    users.wait_for(lambda m: m == {"present": True, "user_id": "ada", "ready": True})
    page.wait_for_selector("#who:text-is('Ada is here')")  # the page says so once it sent it

    # the opening questions: her name typed, then a choice tapped
    decided(decisions, mark, lambda d: d["action"] == "ask" and d["detail"] == "What is your name?")
    page.wait_for_selector(".keyboard .prompt:text('What is your name?')")
    said(page, "What is your name?")
    page.fill(".typed", "Ada")
    mark = decisions.mark()
    page.click(".send")
    asked = decided(decisions, mark, lambda d: d["action"] == "ask")
    assert asked["reason"] == "general_question" and "How often" in asked["detail"]
    page.click("button[data-choice='moderate']")
    screens.wait_for(lambda m: m == {"choice": "moderate"})

    # the menu, with the activities' names and pictures: the quiz
    decided(decisions, mark, lambda d: d["action"] == "start" and d["activity"] == "menu")
    page.wait_for_selector("#screen h2:text('What would you like to do?')")
    quiz_button = page.locator("button[data-choice='quiz']")
    assert quiz_button.inner_text() == "Quiz" and quiz_button.locator(".icon").count() == 1
    assert page.locator(".choices.menu button.activity").count() >= 10
    mark = decisions.mark()
    quiz_button.click()
    started = decided(decisions, mark, lambda d: d["action"] == "start" and d["activity"] == "quiz")
    assert started["chosen_by"] == "user"
    said(page, "Let's play a quiz, Ada!")

    # a round: the question and its four answers, one tapped, the robot's verdict said
    page.wait_for_selector("#screen h2:text('Question 1.')", timeout=60_000)
    answers = page.locator("#screen .choices button")
    assert answers.count() == 4
    answer = answers.first.get_attribute("data-choice")
    answers.first.click()
    screens.wait_for(lambda m: m == {"choice": answer})
    page.wait_for_function(
        "['Correct!', 'Not quite.'].some("
        "w => document.getElementById('caption').textContent.includes(w))"
    )
    SCREENSHOT.parent.mkdir(exist_ok=True)
    page.screenshot(path=str(SCREENSHOT))

    # the right shoulder: "do you want to stop?", confirmed on the screen
    mark = decisions.mark()
    page.click("button[data-part='right_shoulder']")
    decided(decisions, mark, lambda d: d["action"] == "pause" and d["reason"] == "confirm_cancel")
    page.wait_for_selector("button[data-choice='stop']")
    said(page, "Do you want to stop the quiz?")
    page.click("button[data-choice='stop']")
    cancel = decided(decisions, mark, lambda d: d["action"] == "cancel")
    assert cancel["reason"] == "confirm_cancel" and cancel["activity"] == "quiz"

    # the quiz again, ended by the left shoulder: then the robot asks for a rating
    decided(decisions, mark, lambda d: d["action"] == "start" and d["activity"] == "menu")
    mark = decisions.mark()
    page.click("button[data-choice='quiz']")
    decided(decisions, mark, lambda d: d["action"] == "start" and d["activity"] == "quiz")
    page.wait_for_selector("#screen h2:text('Question 1.')", timeout=60_000)
    page.click("button[data-part='left_shoulder']")
    decided(decisions, mark, lambda d: d["action"] == "complete" and d["activity"] == "quiz")
    feedback = decided(decisions, mark, lambda d: d["reason"] == "feedback")
    assert feedback["action"] == "ask"
    page.wait_for_selector(".rating button[data-choice='5']")
    assert page.locator(".rating button").count() == 5
    mark = decisions.mark()
    page.click(".rating button[data-choice='4']")
    screens.wait_for(lambda m: m == {"choice": "4"})
    decided(decisions, mark, lambda d: d["action"] == "start" and d["activity"] == "menu")

    # she leaves; the picker then knows her by the name she gave
    mark = decisions.mark()
    page.click("#leave-button")
    left = decided(decisions, mark, lambda d: d["reason"] == "user_left")
    assert left["action"] == "cancel"
    page.wait_for_selector("#who:text-is('Nobody is here')")
    page.wait_for_selector("button[data-person='ada']:text('Ada')")

    # the session is stored with its timings, as a researcher exports it
    assert face.daemon.terminate() == 0
    events = [row for row in _events(face.daemon.db) if row["user"] == "ada"]
    kinds = [row["event"] for row in events]
    assert kinds[0] == "arrived" and kinds[-1] == "left", kinds
    taps = [r for r in events if r["event"] == "input" and r["channel"] == "screen"]
    assert taps and all(r["delay_s"] not in ("", None) for r in taps if r["offer"])
    assert any(r["event"] == "offered" and r["offer_kind"] == "menu" for r in events)
    assert any(r["event"] == "offered" and r["offer_kind"] == "rating" for r in events)
    assert any(r["event"] == "input" and r["channel"] == "touch" for r in events)
    assert any(r["event"] == "cancelled" and r["activity"] == "quiz" for r in events)


def _events(db: str) -> list[dict[str, str]]:
    """``dms sessions export --events`` as a researcher runs it: one row per event."""
    command = ["sessions", "export", "--events", "--format", "csv", "--db", db]
    done = subprocess.run(
        [sys.executable, "-m", "dms.cli", *command],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 0, done.stderr
    return list(csv.DictReader(io.StringIO(done.stdout)))


def test_the_eyes_follow_the_aim_and_the_cheeks_take_the_led_colour(face: Face, page: Any) -> None:
    eye = "getComputedStyle(document.querySelector('.eye')).transform"
    before = page.evaluate(eye)
    # the daemon's own commands, as it publishes them (a look to its left, orange cheeks)
    put(
        face.session,
        "robot/command",
        {"id": "t-1", "channel": "aim", "action": "look_at", "args": {"joints": {"neck": 0.8}}},
    )
    page.wait_for_function(f"{eye} !== {before!r}")
    page.wait_for_function(f"{eye}.split(',')[4] > 20")  # to its left: the viewer's right
    put(
        face.session,
        "robot/command",
        {"id": "t-2", "channel": "led", "action": "set", "args": {"color": "orange"}},
    )
    page.wait_for_function(
        "getComputedStyle(document.querySelector('.cheek')).backgroundColor === 'rgb(255, 154, 60)'"
    )
    put(
        face.session,
        "robot/command",
        {"id": "t-3", "channel": "speech", "action": "say", "args": {"text": "Hello there"}},
    )
    said(page, "Hello there")
    page.wait_for_selector("#mouth.open")  # it moves while it speaks
