"""``dms studio``'s page in Debian's Chromium, driven by Playwright as a person would.

A new behavior built from an empty canvas with clicks and typing only (a speak state, an
ask with two answers, transitions drawn by dragging), a typo'd placeholder and a wrong
value flagged at their field before saving, the file saved and checked by ``dms behavior
check``, the behavior tried on the simulated Mini with each state lit in turn, and a
shipped behavior opened and saved unchanged, byte for byte. Saves docs/studio.png.
"""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from tests.integration.test_studio import Studio, running_studio, shipped_copy
from tests.integration.viewer_harness import (
    CHROMIUM,
    CHROMIUM_ARGS,
    browser_missing,
    watch_lit,
)

SCREENSHOT = Path(__file__).resolve().parents[2] / "docs" / "studio.png"
WAIT_MS = 15_000

pytestmark = [
    pytest.mark.integration,
    pytest.mark.skipif(browser_missing() is not None, reason=str(browser_missing())),
]


@pytest.fixture(scope="module")
def studio(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Studio]:
    """One studio for the module: its tests touch different behaviors."""
    with running_studio(shipped_copy(tmp_path_factory.mktemp("studio_page"))) as running:
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
def page(studio: Studio, browser: Any) -> Iterator[Any]:
    page = browser.new_page(viewport={"width": 1400, "height": 900})
    errors: list[str] = []
    page.on("pageerror", lambda error: errors.append(str(error)))
    page.set_default_timeout(WAIT_MS)
    yield page
    page.close()
    assert not errors, errors


def ready(page: Any, url: str) -> None:
    page.goto(url)
    page.wait_for_selector("body[data-ready='1']")


def drag(page: Any, source: str, target: str) -> None:
    """Press on ``source``, move over ``target`` and let go there."""
    page.locator(source).hover()
    page.mouse.down()
    box = page.locator(target).bounding_box()
    page.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2, steps=8)
    page.mouse.up()


def message_at(page: Any, param: str, severity: str, saying: str = "") -> str:
    """The first ``severity`` message at the field of ``param`` that says ``saying``."""
    found = page.locator(f'#props .field[data-param="{param}"] .msg.{severity}', has_text=saying)
    found.first.wait_for()
    return str(found.first.inner_text())


def test_a_behavior_built_with_clicks_and_typing_is_saved_and_loads(
    studio: Studio, page: Any
) -> None:
    ready(page, studio.url)
    page.fill("#param-name", "greeting")
    page.click('#palette button[data-block="speak"]')
    page.fill("#param-text", "Hello {user.nmae|there}!")
    said = message_at(page, "text", "error", "{user.nmae}")
    assert said.endswith("user has no field 'nmae'; did you mean {user.name}?"), said
    page.fill("#param-text", "")
    assert "missing parameter 'text'" in message_at(page, "text", "error", "missing")
    page.fill("#param-text", "Hello {user.name|there}! I remember {answr}.")
    assert "answr is no userdata key" in message_at(page, "text", "error", "{answr}")
    page.fill("#param-text", "Hello {user.name|there}!")
    page.click('#palette button[data-block="ask"]')
    page.fill("#param-question", "Shall we listen to some music?")
    page.fill("#param-choices", "yes\nno")
    page.check("#param-branch")
    page.fill("#param-timeout_s", "soon")
    assert "timeout_s" in message_at(page, "timeout_s", "error")
    page.fill("#param-timeout_s", "10")
    page.wait_for_selector('.port[data-path="ASK"][data-port="yes"]')
    drag(page, '.port[data-path="SPEAK"][data-port="done"] .hit', '.state[data-path="ASK"] > rect')
    drag(page, '.port[data-path="ASK"][data-port="yes"] .hit', '.terminal[data-end="done"] rect')
    page.click('.state[data-path="ASK"] > rect')
    page.select_option('select[data-outcome="no"]', "done")
    page.select_option('select[data-outcome="no_answer"]', "done")
    page.wait_for_selector("#status.good")
    page.click("#save-button")
    page.wait_for_selector("body[data-saved='saved']")
    saved = studio.folder / "greeting.yaml"
    checked = subprocess.run(
        [sys.executable, "-m", "dms.cli", "behavior", "check", str(saved)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert checked.returncode == 0, checked.stdout + checked.stderr + saved.read_text()
    text = saved.read_text()
    assert "transitions: {done: ASK}" in text and '"yes": done' in text, text

    watch_lit(page)
    page.click("#run-button")
    page.wait_for_function("document.getElementById('trial-state').textContent.includes('waiting')")
    page.fill("#answer-input", "yes please")
    page.click("#answer-button")
    page.wait_for_function("document.getElementById('trial-state').textContent.includes('ended')")
    assert "ended: done" in page.inner_text("#trial-state")
    assert page.evaluate("window.litSeen") == ["SPEAK", "ASK"]
    assert "Shall we listen" in page.inner_text("#robot")
    assert page.locator("#userdata tr", has_text="answer").count() == 1


def test_a_shipped_behavior_opened_and_saved_unchanged_is_byte_identical(
    studio: Studio, page: Any
) -> None:
    path = studio.folder / "quiz.yaml"
    before = path.read_bytes()
    ready(page, studio.url)
    page.select_option("#open-select", "quiz")
    page.wait_for_selector('.state[data-path="INTRO"]')
    page.wait_for_selector("#status.good")
    page.click("#save-button")
    page.wait_for_selector("body[data-saved='saved']")
    assert path.read_bytes() == before

    page.click("#run-button")
    page.wait_for_function("document.getElementById('trial-state').textContent.includes('waiting')")
    page.wait_for_selector(".state.lit")
    page.screenshot(path=str(SCREENSHOT))
    page.click("#stop-button")


def slide(page: Any, joint: str, fraction: float) -> None:
    """Drag the slider of ``joint`` with the mouse to ``fraction`` of its track."""
    box = page.locator(f"#joint-{joint}").bounding_box()
    y = box["y"] + box["height"] / 2
    page.mouse.move(box["x"] + box["width"] / 2, y)
    page.mouse.down()
    page.mouse.move(box["x"] + box["width"] * fraction, y, steps=8)
    page.mouse.up()


def posed(page: Any, joint: str, test: str) -> dict[str, float]:
    """The simulated Mini's joints once ``joint`` satisfies ``test`` (a JS comparison) and
    the studio has what its slider shows."""
    page.wait_for_function(
        f"(() => {{ const p = JSON.parse(document.body.dataset.posed || '{{}}');"
        f" const shown = Number(document.getElementById('joint-{joint}').value);"
        f" return p.{joint} === shown && p.{joint} {test}; }})()"
    )
    return dict(json.loads(page.get_attribute("body", "data-posed")))


def test_a_pose_set_by_the_sliders_is_recorded_timed_and_played_back(
    studio: Studio, page: Any
) -> None:
    ready(page, studio.url)
    page.fill("#param-name", "wave_hello")
    page.click('#palette button[data-block="pose"]')
    page.wait_for_selector("#play-pose")
    slide(page, "neck", 0.85)
    slide(page, "left_arm", 0.7)
    posed(page, "neck", "> 0.4")
    first = posed(page, "left_arm", "> 1.2")
    page.click("#record-button")
    row = page.locator('tr[data-keyframe="0"]')
    row.wait_for()
    assert float(row.locator('input[data-joint="neck"]').input_value()) == first["neck"]
    assert float(row.locator('input[data-joint="left_arm"]').input_value()) == first["left_arm"]
    page.fill('input[data-seconds="0"]', "1.5")
    page.keyboard.press("Tab")
    slide(page, "neck", 0.2)
    second = posed(page, "neck", "< -0.3")
    page.click("#record-button")
    page.locator('tr[data-keyframe="1"]').wait_for()
    page.wait_for_selector("#status.good")

    page.click("#play-pose")
    page.wait_for_function("document.getElementById('trial-state').textContent.includes('ended')")
    assert "ended: done" in page.inner_text("#trial-state")
    played = json.loads(page.get_attribute("#robot", "data-joints"))
    assert played == pytest.approx(second, abs=0.01)
    sent = page.locator("#log li", has_text="motion.pose").all_inner_texts()
    assert len(sent) == 2 and '"duration_s":1.5' in sent[0], sent
    page.screenshot(path=str(studio.folder.parent / "posed.png"))

    page.click("#save-button")
    page.wait_for_selector("body[data-saved='saved']")
    saved = studio.folder / "wave_hello.yaml"
    checked = subprocess.run(
        [sys.executable, "-m", "dms.cli", "behavior", "check", str(saved)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert checked.returncode == 0, checked.stdout + checked.stderr
    assert "seconds: [1.5]" in saved.read_text(), saved.read_text()


def drag_by(page: Any, selector: str, dx: float, dy: float) -> None:
    """Press on ``selector``'s centre and move the mouse by (dx, dy) pixels, then let go."""
    box = page.locator(selector).bounding_box()
    x, y = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
    page.mouse.move(x, y)
    page.mouse.down()
    page.mouse.move(x + dx, y + dy, steps=10)
    page.mouse.up()


def test_the_mini_is_posed_by_dragging_its_figure_and_the_pose_recorded(
    studio: Studio, page: Any
) -> None:
    ready(page, studio.url)
    page.fill("#param-name", "look_and_raise")
    page.click('#palette button[data-block="pose"]')
    page.wait_for_selector("#figure")
    page.click("#posing button:has-text('Neutral')")  # the module's robot, as others left it
    posed(page, "neck", "=== 0")
    # The head dragged to the drawing's right: the robot looks to its left, and down.
    drag_by(page, "#figure .skull", 40, 15)
    head = posed(page, "neck", "> 0.4")
    assert 0.1 < head["head"] <= 0.45, head
    # Its left hand (on the drawing's right) dragged out and up: the arm raised.
    drag_by(page, '#figure [data-part="left_arm"] .hand', 40, -60)
    raised = posed(page, "left_arm", "> 1.5")
    # The body dragged to the left, past its limit: the hip stops at -1.2.
    drag_by(page, "#figure .torso", -150, 0)
    turned = posed(page, "hip", "< -1.1")
    assert turned["hip"] == -1.2 and turned["neck"] == raised["neck"], turned
    assert float(page.input_value("#joint-hip")) == -1.2
    page.click("#record-button")
    row = page.locator('tr[data-keyframe="0"]')
    row.wait_for()
    kept = {
        joint: float(row.locator(f'input[data-joint="{joint}"]').input_value()) for joint in turned
    }
    assert kept == pytest.approx(turned, abs=1e-9), (kept, turned)


def test_a_task_frame_is_declared_in_a_form_and_aimed_at_by_name(studio: Studio, page: Any) -> None:
    ready(page, studio.url)
    page.fill("#param-name", "fetch_cup")
    for label, value in [("name", "handle"), ("of", "object:tag7"), ("xyz[2] (m)", "0.1")]:
        page.fill(f'[aria-label="task frame 1 {label}"]', value)
        page.keyboard.press("Tab")
    page.wait_for_selector('#frames option[value="handle"]', state="attached")
    page.click('#palette button[data-block="look_at"]')
    page.fill("#param-frame", "handel")
    said = message_at(page, "frame", "error", "handel")
    assert said.endswith("no task frame 'handel'; did you mean 'handle'?"), said
    page.fill("#param-frame", "handle")
    page.select_option('select[data-outcome="lost"]', "done")
    page.wait_for_selector("#status.good")
    page.click("#save-button")
    page.wait_for_selector("body[data-saved='saved']")
    saved = studio.folder / "fetch_cup.yaml"
    assert "handle: {of: object:tag7, xyz: [0, 0, 0.1]}" in saved.read_text(), saved.read_text()
    checked = subprocess.run(
        [sys.executable, "-m", "dms.cli", "behavior", "check", str(saved)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert checked.returncode == 0, checked.stdout + checked.stderr


def test_a_robot_parameter_and_a_medium_are_offered_and_a_typo_of_either_is_flagged(
    studio: Studio, page: Any
) -> None:
    ready(page, studio.url)
    page.fill("#param-name", "announce")
    page.click('#palette button[data-block="speak"]')
    page.fill("#param-text", "My volume is {robot.volumne}.")
    said = message_at(page, "text", "error", "{robot.volumne}")
    assert said.endswith("robot has no parameter 'volumne'; did you mean {robot.voicevolume}?")
    page.fill("#param-text", "My volume is {robot.voicevolume}.")
    page.click('#palette button[data-block="play_media"]')
    page.fill("#param-title", "Boleros")
    # the media the shipped content lists are offered at the field
    page.wait_for_selector(
        '#suggest-file option[value="media/music/boleros.mp3"]', state="attached"
    )
    assert page.get_attribute("#param-file", "list") == "suggest-file"
    drag(
        page,
        '.port[data-path="SPEAK"][data-port="done"] .hit',
        '.state[data-path="PLAY_MEDIA"] > rect',
    )
    page.click('.state[data-path="PLAY_MEDIA"] > rect')
    page.fill("#param-file", "media/music/bolero.mp3")
    said = message_at(page, "file", "error", "bolero.mp3")
    assert said.endswith("did you mean 'media/music/boleros.mp3'?"), said
    page.fill("#param-file", "media/music/boleros.mp3")
    page.wait_for_selector("#status.good")
    page.click("#save-button")
    page.wait_for_selector("body[data-saved='saved']")
    saved = studio.folder / "announce.yaml"
    checked = subprocess.run(
        [sys.executable, "-m", "dms.cli", "behavior", "check", str(saved)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert checked.returncode == 0, checked.stdout + checked.stderr + saved.read_text()
