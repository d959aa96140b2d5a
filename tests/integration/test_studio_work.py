"""``dms studio`` never loses a designer's work, driven in Debian's Chromium with the mouse.

Edits survive an Open until the designer confirms the discard (and Undo brings them
back), the modified mark, the draft kept in the browser and offered back, the tab that
warns before it closes, a file changed on disk compared and overwritten knowingly, a
state placed by hand that keeps its place (beside the file, the YAML byte-identical),
several states moved and deleted together, transitions drawn in quick succession, and
every shipped behavior opened and saved from the page byte for byte.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from typing import Any

import pytest

from activities.library import BEHAVIORS_DIR
from tests.integration.test_studio import Studio, running_studio, shipped_copy
from tests.integration.viewer_harness import CHROMIUM, CHROMIUM_ARGS, browser_missing

WAIT_MS = 15_000

pytestmark = [
    pytest.mark.integration,
    pytest.mark.skipif(browser_missing() is not None, reason=str(browser_missing())),
]


@pytest.fixture(scope="module")
def studio(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Studio]:
    with running_studio(shipped_copy(tmp_path_factory.mktemp("studio_work"))) as running:
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
def context(browser: Any) -> Iterator[Any]:
    """A browser profile of its own (its storage keeps the drafts); no page error."""
    context = browser.new_context(viewport={"width": 1400, "height": 900})
    context.set_default_timeout(WAIT_MS)
    errors: list[str] = []
    context.on("weberror", lambda error: errors.append(str(error.error)))
    yield context
    context.close()
    assert not errors, errors


def opened(context: Any, studio: Studio, name: str | None = None) -> Any:
    page = context.new_page()
    page.goto(studio.url + (f"&open={name}" if name else ""))
    page.wait_for_selector("body[data-ready='1']")
    page.wait_for_selector("body[data-checked]")  # the canvas is drawn anew after a check
    return page


def answer(page: Any, choice: str) -> None:
    """Press the button ``choice`` of the dialog the studio shows."""
    page.click(f"dialog#ask[open] button[data-choice='{choice}']")
    page.wait_for_selector("dialog#ask", state="hidden")


def state_at(page: Any, path: str) -> tuple[float, float]:
    """Where a state is drawn, in the canvas's units (its transform)."""
    transform = page.get_attribute(f'.state[data-path="{path}"]', "transform")
    x, y = transform.removeprefix("translate(").removesuffix(")").split(",")
    return float(x), float(y)


def box_of(page: Any, selector: str) -> dict[str, float]:
    """Where an element is on the page; the canvas is drawn anew after each check, so an
    element measured as it is replaced is measured again (its copy is at the same place)."""
    for _ in range(20):
        page.locator(selector).wait_for()
        found = page.locator(selector).bounding_box()
        if found is not None:
            return dict(found)
    raise AssertionError(f"{selector} is never on the page long enough to be measured")


def mouse_drag(page: Any, selector: str, dx: float, dy: float) -> None:
    box = box_of(page, selector)
    x, y = box["x"] + 30, box["y"] + 12
    page.mouse.move(x, y)
    page.mouse.down()
    page.mouse.move(x + dx, y + dy, steps=10)
    page.mouse.up()


def drag_to(page: Any, source: str, target: str) -> None:
    """Press at the centre of ``source``, move over ``target`` and let go."""
    box = box_of(page, source)
    page.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
    page.mouse.down()
    to = box_of(page, target)
    page.mouse.move(to["x"] + to["width"] / 2, to["y"] + to["height"] / 2, steps=6)
    page.mouse.up()


def test_edits_survive_an_open_until_the_designer_confirms(studio: Studio, context: Any) -> None:
    page = opened(context, studio, "quiz")
    page.wait_for_selector('.state[data-path="INTRO"]')
    assert page.get_attribute("body", "data-modified") == "0"
    page.click('.state[data-path="INTRO"] > rect')
    page.fill("#param-text", "Welcome to the quiz, my friend!")
    page.wait_for_selector("body[data-modified='1']")
    assert page.locator("#doc-title.modified").count() == 1
    assert page.title().startswith("●")

    page.select_option("#open-select", "jokes")
    page.wait_for_selector("dialog#ask[open]")
    assert "quiz has changes not saved" in page.inner_text("dialog#ask h2")
    answer(page, "cancel")
    assert page.input_value("#open-select") == "quiz"
    assert page.input_value("#param-text") == "Welcome to the quiz, my friend!"
    assert page.get_attribute("body", "data-modified") == "1"

    page.select_option("#open-select", "jokes")
    answer(page, "discard")
    page.wait_for_function("document.getElementById('doc-title').textContent.startsWith('jokes')")
    assert page.get_attribute("body", "data-modified") == "0"
    assert "Welcome to the quiz" not in (studio.folder / "quiz.yaml").read_text()

    page.click("#undo-button")  # back past the Open, the edit with it
    page.wait_for_function("document.getElementById('doc-title').textContent.startsWith('quiz')")
    assert page.get_attribute("body", "data-modified") == "1"
    assert page.input_value("#open-select") == "quiz"
    page.click('.state[data-path="INTRO"] > rect')
    assert page.input_value("#param-text") == "Welcome to the quiz, my friend!"

    # the tab asks before it closes on edits not saved ...
    page.wait_for_selector("body[data-drafted]")
    asked: list[str] = []

    def on_dialog(dialog: Any) -> None:
        asked.append(dialog.type)
        dialog.accept()

    page.on("dialog", on_dialog)
    with page.expect_event("close"):
        page.close(run_before_unload=True)
    assert asked == ["beforeunload"]
    # ... and the page opened again offers them back from the browser's storage
    again = opened(context, studio, "quiz")
    again.wait_for_selector("dialog#ask[open]")
    assert "Edits of quiz.yaml not saved" in again.inner_text("dialog#ask h2")
    answer(again, "restore")
    again.wait_for_selector("body[data-modified='1']")
    again.click('.state[data-path="INTRO"] > rect')
    assert again.input_value("#param-text") == "Welcome to the quiz, my friend!"
    again.screenshot(path=str(studio.folder.parent / "restored.png"))


def test_a_file_changed_on_disk_is_compared_then_overwritten_knowingly(
    studio: Studio, context: Any
) -> None:
    path = studio.folder / "jokes.yaml"
    page = opened(context, studio, "jokes")
    page.fill("#param-description", "Jokes, told one by one.")
    page.wait_for_selector("body[data-modified='1']")
    path.write_text(path.read_text() + "# a note another program wrote\n")

    page.click("#save-button")
    page.wait_for_selector("dialog#ask[open]")
    assert "jokes.yaml changed on disk" in page.inner_text("dialog#ask h2")
    page.click("dialog#ask[open] button[data-choice='compare']")
    page.wait_for_selector("dialog#ask[open] .diff")
    added = page.locator("dialog#ask .diff .add").all_inner_texts()
    assert any("Jokes, told one by one." in line for line in added), added
    page.screenshot(path=str(studio.folder.parent / "compare.png"))
    answer(page, "overwrite")
    page.wait_for_selector("body[data-modified='0']")
    text = path.read_text()
    assert "Jokes, told one by one." in text and "# a note another program wrote" in text


def test_a_state_placed_by_hand_keeps_its_place_and_the_yaml_is_unchanged(
    studio: Studio, context: Any
) -> None:
    path = studio.folder / "sayings.yaml"
    before = path.read_bytes()
    page = opened(context, studio, "sayings")
    first = page.locator(".state").first.get_attribute("data-path")
    assert first is not None
    x, y = state_at(page, first)
    mouse_drag(page, f'.state[data-path="{first}"] > rect', 0, 140)
    page.wait_for_selector("body[data-modified='1']")
    moved = state_at(page, first)
    assert moved[1] > y + 40 and abs(moved[0] - x) < 1, (x, y, moved)

    page.click("#save-button")
    page.wait_for_selector("body[data-modified='0']")
    assert path.read_bytes() == before
    sidecar = json.loads((studio.folder / "sayings.layout.json").read_text())
    assert sidecar["positions"][first] == [round(moved[0]), round(moved[1])]

    again = opened(context, studio, "sayings")
    again.wait_for_selector(f'.state[data-path="{first}"]')
    assert state_at(again, first) == (round(moved[0]), round(moved[1]))
    again.screenshot(path=str(studio.folder.parent / "placed.png"))
    again.click("#arrange")  # laid out again: back where the layout puts it
    again.wait_for_selector("body[data-modified='1']")
    assert state_at(again, first) == (x, y)
    again.click("#save-button")
    again.wait_for_selector("body[data-modified='0']")
    assert path.read_bytes() == before
    assert json.loads((studio.folder / "sayings.layout.json").read_text()) == {"positions": {}}


def test_several_states_move_and_go_together_and_quick_drags_are_kept(
    studio: Studio, context: Any
) -> None:
    page = opened(context, studio)
    for _ in range(3):
        page.click('#palette button[data-block="speak"]')
    page.wait_for_selector('.state[data-path="SPEAK_3"]')
    for name in ("SPEAK", "SPEAK_2", "SPEAK_3"):  # every new state is in view
        box = box_of(page, f'.state[data-path="{name}"] > rect')
        canvas = box_of(page, "#canvas")
        assert canvas["x"] <= box["x"] and box["x"] + box["width"] <= canvas["x"] + canvas["width"]

    # three transitions drawn one after the other, without waiting for the checks
    port = '.port[data-path="{}"][data-port="done"] .hit'
    drag_to(page, port.format("SPEAK"), '.state[data-path="SPEAK_2"] > rect')
    drag_to(page, port.format("SPEAK_2"), '.state[data-path="SPEAK_3"] > rect')
    # the centre of a connected dot starts a new transition too (it does not pan)
    drag_to(page, port.format("SPEAK"), '.state[data-path="SPEAK_3"] > rect')
    page.wait_for_selector('.edge[data-from="SPEAK"][data-to="SPEAK_3"]')
    assert page.locator('.edge[data-from="SPEAK_2"][data-to="SPEAK_3"]').count() == 1
    assert page.locator('.edge[data-from="SPEAK"][data-to="SPEAK_2"]').count() == 0

    page.click('.state[data-path="SPEAK_2"] > rect')
    page.click('.state[data-path="SPEAK_3"] > rect', modifiers=["Shift"])
    page.wait_for_selector("body[data-selected='2']")
    two, three, one = (state_at(page, n) for n in ("SPEAK_2", "SPEAK_3", "SPEAK"))
    mouse_drag(page, '.state[data-path="SPEAK_2"] > rect', 0, 120)
    page.wait_for_function(
        f"document.querySelector('.state[data-path=\"SPEAK_3\"]').getAttribute('transform')"
        f" !== 'translate({three[0]},{three[1]})'"
    )
    moved2, moved3 = state_at(page, "SPEAK_2"), state_at(page, "SPEAK_3")
    assert moved2[1] - two[1] == pytest.approx(moved3[1] - three[1], abs=1)
    assert state_at(page, "SPEAK") == one

    # copied and pasted together: the transition between them goes to the copy
    page.keyboard.press("Control+c")
    page.keyboard.press("Control+v")
    page.wait_for_selector('.edge[data-from="SPEAK_2_2"][data-to="SPEAK_3_2"]')
    assert page.get_attribute("body", "data-selected") == "2"
    page.click("#undo-button")
    page.wait_for_selector('.state[data-path="SPEAK_2_2"]', state="detached")
    page.click('.state[data-path="SPEAK_2"] > rect')
    page.click('.state[data-path="SPEAK_3"] > rect', modifiers=["Shift"])
    page.wait_for_selector("body[data-selected='2']")

    page.keyboard.press("Delete")
    page.wait_for_selector('.state[data-path="SPEAK_3"]', state="detached")
    assert page.locator('.state[data-path="SPEAK_2"]').count() == 0
    page.click("#undo-button")
    page.wait_for_selector('.state[data-path="SPEAK_3"]')
    assert page.locator('.state[data-path="SPEAK_2"]').count() == 1


def test_every_shipped_behavior_saved_from_the_page_is_byte_identical(
    studio: Studio, context: Any
) -> None:
    page = opened(context, studio)
    names = sorted(path.stem for path in BEHAVIORS_DIR.glob("*.yaml"))
    assert len(names) >= 10
    for name in names:
        path = studio.folder / f"{name}.yaml"
        if name in ("jokes", "quiz", "news", "dance"):  # the other tests here changed them
            path.write_bytes((BEHAVIORS_DIR / f"{name}.yaml").read_bytes())
        before = path.read_bytes()
        page.select_option("#open-select", name)
        page.wait_for_function(
            f"document.getElementById('doc-title').textContent.includes('({name}.yaml)')"
        )
        page.evaluate("document.body.dataset.saved = ''")
        page.click("#save-button")
        page.wait_for_selector("body[data-saved='saved']")
        assert path.read_bytes() == before, name
        assert page.get_attribute("body", "data-modified") == "0"
    assert not (studio.folder / "drafts").exists()


def test_an_outcome_map_and_userdata_are_edited_in_forms(studio: Studio, context: Any) -> None:
    page = opened(context, studio, "dance")
    page.click('.state[data-path="DANCE"] > text.name')
    music = page.locator('select[data-map="done/MUSIC"]')
    assert music.input_value() == "done"
    page.select_option('select[data-map="done/MUSIC"]', "")
    page.wait_for_selector("body[data-modified='1']")
    page.select_option('select[data-map="done/MUSIC"]', "done")
    page.wait_for_selector("body[data-modified='0']")  # back as the file has it
    page.click("#zoom-fit")
    page.click("#canvas", position={"x": 5, "y": 5})  # nothing selected: the behavior
    page.fill('[aria-label="userdata name 1"]', "round")
    page.fill('[aria-label="userdata value 1"]', "3")
    page.keyboard.press("Tab")
    page.wait_for_selector("#status.good")
    page.click("#save-button")
    page.wait_for_selector("body[data-modified='0']")
    text = (studio.folder / "dance.yaml").read_text()
    assert "userdata:" in text and "round: 3" in text, text
    assert "outcome_map: {done: {MUSIC: done}}" in text


def test_a_new_behavior_not_saved_is_offered_back_until_it_is_saved(
    studio: Studio, context: Any
) -> None:
    page = opened(context, studio)
    page.fill("#param-name", "kept_draft")
    page.click('#palette button[data-block="speak"]')
    page.fill("#param-text", "Hello again.")
    page.wait_for_selector("body[data-drafted]")
    page.close()

    again = opened(context, studio)  # the page opened again, without a file
    again.wait_for_selector("dialog#ask[open]")
    assert "Edits of a new behavior not saved" in again.inner_text("dialog#ask h2")
    answer(again, "restore")
    again.wait_for_selector('.state[data-path="SPEAK"]')
    again.wait_for_selector("#status.good")
    again.click("#save-button")
    again.wait_for_selector("body[data-saved='saved']")
    assert "Hello again." in (studio.folder / "kept_draft.yaml").read_text()
    # the dialog opens as the page becomes ready, if it opens at all
    third = opened(context, studio)
    assert third.locator("dialog#ask[open]").count() == 0


def test_a_file_changed_on_disk_while_the_page_was_away_is_offered_for_reload(
    studio: Studio, context: Any
) -> None:
    path = studio.folder / "news.yaml"
    page = opened(context, studio, "news")
    changed = path.read_text().replace("description: Reads", "description: Fresh. Reads", 1)
    assert changed != path.read_text()
    path.write_text(changed)
    page.evaluate("window.dispatchEvent(new Event('focus'))")  # the page comes to the front
    page.wait_for_selector("dialog#ask[open]")
    assert "news.yaml changed on disk" in page.inner_text("dialog#ask h2")
    answer(page, "reload")
    page.wait_for_function(
        "document.getElementById('param-description').value.startsWith('Fresh.')"
    )
    assert page.get_attribute("body", "data-modified") == "0"
    page.click("#undo-button")  # the page as it was before the reload
    page.wait_for_function(
        "!document.getElementById('param-description').value.startsWith('Fresh.')"
    )
