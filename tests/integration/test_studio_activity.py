"""The studio's Activity form in Debian's Chromium, driven by Playwright as a designer
would: a new behavior declared an activity with clicks and typing, a wrong feature value
flagged at the form before saving, the file saved with its ``activity:`` key and checked
by ``dms behavior check``, then opened again with the form filled."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Iterator
from typing import Any

import pytest
import yaml

from tests.integration.test_studio import Studio, running_studio, shipped_copy
from tests.integration.viewer_harness import CHROMIUM, CHROMIUM_ARGS, browser_missing

WAIT_MS = 15_000

pytestmark = [
    pytest.mark.integration,
    pytest.mark.skipif(browser_missing() is not None, reason=str(browser_missing())),
]


@pytest.fixture
def page(tmp_path: Any) -> Iterator[tuple[Studio, Any]]:
    from playwright.sync_api import sync_playwright

    with (
        running_studio(shipped_copy(tmp_path)) as studio,
        sync_playwright() as playwright,
    ):
        browser = playwright.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
        try:
            page = browser.new_page(viewport={"width": 1400, "height": 1000})
            errors: list[str] = []
            page.on("pageerror", lambda error: errors.append(str(error)))
            page.set_default_timeout(WAIT_MS)
            yield studio, page
            assert not errors, errors
        finally:
            browser.close()


def test_a_behavior_is_declared_an_activity_in_the_form_and_saved(
    page: tuple[Studio, Any],
) -> None:
    studio, browser_page = page
    p = browser_page
    p.goto(studio.url)
    p.wait_for_selector("body[data-ready='1']")
    p.fill("#param-name", "song_or_chat")
    p.click('#palette button[data-block="speak"]')
    p.fill("#param-text", "La la la, a little song for you.")
    p.click("#canvas")  # nothing selected: the behavior's own settings, and its Activity form
    p.wait_for_selector("#activity-declared")
    assert not p.is_visible("#param-menu")  # not an activity until asked
    p.check("#activity-declared")
    p.select_option("#param-manager", '"entertainment"')
    p.fill("#param-menu", "Song or chat")
    p.fill("#param-expected_s", "90")
    p.fill("#param-hobbies", "musik")
    found = p.locator('#props .field[data-param="activity"] .msg.error')
    found.first.wait_for()
    assert "feature hobbies: 'musik' is not one of" in found.first.inner_text()
    p.fill("#param-hobbies", "music")
    p.fill("#param-age", "65\n100")
    p.wait_for_selector("#status.good")
    p.click("#save-button")
    p.wait_for_selector("body[data-saved='saved']")
    saved = studio.folder / "song_or_chat.yaml"
    checked = subprocess.run(
        [sys.executable, "-m", "dms.cli", "behavior", "check", str(saved)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert checked.returncode == 0, checked.stdout + checked.stderr + saved.read_text()
    assert yaml.safe_load(saved.read_text())["activity"] == {
        "manager": "entertainment",
        "menu": "Song or chat",
        "expected_s": 90,
        "features": {"hobbies": ["music"], "age": [65, 100]},
    }
    p.goto(studio.url)  # opened again, the form shows what the file holds
    p.wait_for_selector("body[data-ready='1']")
    p.select_option("#open-select", "song_or_chat")
    p.wait_for_selector("#status.good")
    p.click("#canvas")
    assert p.is_checked("#activity-declared")
    assert p.input_value("#param-menu") == "Song or chat"
