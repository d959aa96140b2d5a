"""``dms studio --connect`` beside a real ``dms run``, its page in Debian's Chromium.

From an empty canvas, with clicks and typing only: a speak, an ask with two answers
whose branches go different ways, a look_at the user's face, and a pose whose keyframe
the Record button takes from the simulated Mini's joints (turned by the look_at, run
alone); a rename followed by the transitions, undone and redone; a state copied, pasted
and deleted. Tried on the simulated Mini with each state lit in turn, saved, and then
the daemon reloads its folder and runs it on a ``request`` (each wait is for the
decision or the state on the bus). The same behavior tried on the daemon's robot from
the page (its joints recorded there too), and refused while a session is open. On the
daemon's robot too, a behavior goes state by state (held at each until the next Step)
and one state runs alone. The rules pane shows a verifier finding at its line, the line
`dms rules check` prints.
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
import zenoh

from dms.rules import loader as rules_loader
from tests.integration.harness import Collector, DaemonProcess, client_session, put
from tests.integration.test_studio import Studio, running_studio, shipped_copy
from tests.integration.viewer_harness import (
    CHROMIUM,
    CHROMIUM_ARGS,
    browser_missing,
    watch_lit,
)

EXAMPLE_RULES = Path(rules_loader.__file__).parent / "examples" / "decisions.dmsl"
WAIT_MS = 20_000
BUS_WAIT_S = 20.0

pytestmark = [
    pytest.mark.integration,
    pytest.mark.skipif(browser_missing() is not None, reason=str(browser_missing())),
]


@dataclass
class Bench:
    """A daemon, a studio connected to it, the test's Zenoh session and a browser."""

    studio: Studio
    daemon: DaemonProcess
    session: zenoh.Session
    browser: Any


@pytest.fixture(scope="module")
def bench(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Bench]:
    from playwright.sync_api import sync_playwright

    tmp = tmp_path_factory.mktemp("studio_daemon")
    folder = shipped_copy(tmp)
    (folder / "jokes.yaml").unlink()  # the page builds it again, from nothing
    shutil.copy(EXAMPLE_RULES, folder / "decisions.dmsl")
    daemon = DaemonProcess(tmp, extra_config=f'\n[behaviors]\nfolder = "{folder}"\n')
    session = client_session(daemon.port)
    try:
        daemon.start(session)
        connect = ("--connect", f"tcp/127.0.0.1:{daemon.port}")
        with running_studio(folder, connect) as studio, sync_playwright() as playwright:
            browser = playwright.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
            try:
                yield Bench(studio, daemon, session, browser)
            finally:
                browser.close()
    finally:
        daemon.kill()
        session.close()


@pytest.fixture
def page(bench: Bench) -> Iterator[Any]:
    page = bench.browser.new_page(viewport={"width": 1400, "height": 900})
    errors: list[str] = []
    page.on("pageerror", lambda error: errors.append(str(error)))
    page.set_default_timeout(WAIT_MS)
    page.goto(bench.studio.url)
    page.wait_for_selector("body[data-ready='1']")
    yield page
    page.close()
    assert not errors, errors


def add(page: Any, block: str, name: str) -> None:
    """Click ``block`` in the palette; the new state is selected: wait for its form."""
    page.click(f'#palette button[data-block="{block}"]')
    page.wait_for_selector(f'.state[data-path="{name}"]')


def select_state(page: Any, name: str) -> None:
    page.click("#zoom-fit")  # new states may lie outside the view
    page.click(f'.state[data-path="{name}"] > rect')
    page.wait_for_function(f"document.getElementById('state-name')?.value === {json.dumps(name)}")


def go(page: Any, state: str, outcome: str, target: str) -> None:
    select_state(page, state)
    page.select_option(f'select[data-outcome="{outcome}"]', target)


def trial_text(page: Any, words: str) -> None:
    try:
        page.wait_for_function(
            f"document.getElementById('trial-state').textContent.includes({json.dumps(words)})"
        )
    except Exception:
        shown = page.inner_text("#trial-state"), page.inner_text("#status"), page.inner_text("#log")
        raise AssertionError(f"no {words!r} in the trial's line: {shown}") from None


def test_a_behavior_built_from_nothing_runs_on_the_simulated_mini_and_on_the_daemon(
    bench: Bench, page: Any
) -> None:
    studio, session = bench.studio, bench.session
    page.fill("#param-name", "jokes")
    add(page, "speak", "SPEAK")
    page.fill("#param-text", "A joke.")
    add(page, "ask", "ASK")
    page.fill("#param-question", "Another?")
    page.fill("#param-choices", "yes\nno")
    page.check("#param-branch")
    page.fill("#param-timeout_s", "1")
    add(page, "look_at", "LOOK_AT")
    assert page.locator("#frames option[value='user']").count() == 1
    page.fill("#param-frame", "user")

    # The pose's keyframe is the simulated Mini's joints after it looked at the user.
    page.click("#run-state-button")
    trial_text(page, "ended: done")
    neck = float(page.inner_text("#robot .joints").split("neck ")[1].split()[0])
    assert neck > 0.2, page.inner_text("#robot")
    add(page, "pose", "POSE")
    page.click("#record-button")
    page.wait_for_selector("#status:has-text('recorded pose into keyframes')")
    assert page.locator("tr[data-keyframe]").count() == 1
    recorded = page.input_value('tr[data-keyframe="0"] input[data-joint="neck"]')
    assert float(recorded) == pytest.approx(neck, abs=0.01)

    go(page, "SPEAK", "done", "ASK")
    go(page, "ASK", "yes", "LOOK_AT")
    go(page, "ASK", "no", "POSE")
    go(page, "ASK", "no_answer", "POSE")
    go(page, "LOOK_AT", "done", "POSE")
    go(page, "LOOK_AT", "lost", "POSE")
    go(page, "POSE", "done", "done")

    # Rename follows the transitions; undo and redo take it back and forth.
    select_state(page, "POSE")
    page.fill("#state-name", "NOD")
    page.press("#state-name", "Enter")
    page.wait_for_selector('.state[data-path="NOD"]')
    select_state(page, "LOOK_AT")
    assert page.input_value('select[data-outcome="done"]') == "NOD"
    page.click("#undo-button")
    page.wait_for_selector('.state[data-path="POSE"]')
    page.click("#redo-button")
    page.wait_for_selector('.state[data-path="NOD"]')
    # Copy and paste a state, then delete the copy.
    select_state(page, "SPEAK")
    page.click('#props button[data-action="copy"]')
    page.click('#props button[data-action="paste"]')
    page.wait_for_selector('.state[data-path="SPEAK_2"]')
    assert page.input_value("#param-text") == "A joke."
    page.click('#props button[data-action="delete"]')
    page.wait_for_selector('.state[data-path="SPEAK_2"]', state="detached")

    page.wait_for_selector("#status.good")
    page.click("#save-button")
    page.wait_for_selector("body[data-saved='saved']")
    saved = (studio.folder / "jokes.yaml").read_text()
    assert "  NOD:\n    pose:\n      keyframes:\n" in saved, saved
    assert f"neck: {recorded}" in saved and "{done: NOD, lost: NOD}" in saved, saved

    # Tried on the simulated Mini: each state lit in turn.
    watch_lit(page)
    page.click("#run-button")
    trial_text(page, "waiting")
    page.fill("#answer-input", "yes")
    page.click("#answer-button")
    trial_text(page, "ended: done")
    assert page.evaluate("window.litSeen") == ["SPEAK", "ASK", "LOOK_AT", "NOD"]

    # The daemon takes the saved file on a reload, and runs it on a request.
    decisions = Collector(session, "robots/mini/dms/decision")
    states = Collector(session, "robots/mini/dms/state")
    commands = Collector(session, "robots/mini/robot/command")
    reloads = states.wait_count(1)[-1]["reloads"]
    put(session, "request", {"action": "reload_rules", "by": "test"})
    states.wait_for(lambda s: s["reloads"] > reloads, BUS_WAIT_S)
    put(session, "request", {"action": "start", "activity": "jokes", "by": "caregiver"})
    decisions.wait_for(lambda d: d["action"] == "start" and d["activity"] == "jokes", BUS_WAIT_S)
    commands.wait_for(lambda c: c["args"].get("text") == "A joke.", BUS_WAIT_S)
    commands.wait_for(lambda c: c["action"] == "pose", BUS_WAIT_S)
    done = decisions.wait_for(lambda d: d["action"] in ("complete", "fail"), BUS_WAIT_S)
    assert done["action"] == "complete" and done["activity"] == "jokes", done

    # Tried on the daemon's robot from the page; refused while a session is open.
    watch_lit(page)
    page.select_option("#try-on", "daemon")
    tries = Collector(session, "robots/mini/dms/try")
    page.click("#run-button")
    assert tries.wait_for(lambda t: t["finished"], BUS_WAIT_S)["outcome"] == "done"
    trial_text(page, "ended: done")
    # nobody is in front of the daemon's robot: the look_at is lost at once
    assert page.evaluate("window.litSeen") == ["SPEAK", "ASK", "NOD"]
    # Record takes the daemon's robot's joints (robot/joints) when the trial runs there.
    select_state(page, "SPEAK")
    page.click("#record-button")
    page.wait_for_selector("#status:has-text('recorded pose: hip')")
    put(session, "perception/user", {"present": True, "user_id": "ann", "ready": True})
    states.wait_for(lambda s: (s["user"] or {}).get("id") == "ann", BUS_WAIT_S)
    page.click("#run-button")
    trial_text(page, "refused")
    assert "a session is open (ann)" in page.inner_text("#status")
    put(session, "perception/user", {"present": False, "user_id": None, "ready": False})
    states.wait_for(lambda s: s["user"] is None, BUS_WAIT_S)


STEPS = """\
name: steps
outcomes: [done]
states:
  ONE:
    show: {text: one}
    transitions: {done: TWO}
  TWO:
    show: {text: two}
    transitions: {done: THREE}
  THREE:
    show: {text: three}
    transitions: {done: SEEN}
  SEEN:
    set_data: {values: {seen: three}}
    transitions: {done: done}
"""


def test_on_the_daemons_robot_a_behavior_goes_state_by_state_and_one_state_runs_alone(
    bench: Bench, page: Any
) -> None:
    (bench.studio.folder / "steps.yaml").write_text(STEPS)
    page.goto(f"{bench.studio.url}&open=steps")
    page.wait_for_selector('.state[data-path="THREE"]')
    page.select_option("#try-on", "daemon")
    tries = Collector(bench.session, "robots/mini/dms/try")
    commands = Collector(bench.session, "robots/mini/robot/command")
    watch_lit(page)

    page.click("#step-button")
    for state in ("ONE", "TWO", "THREE"):
        trial_text(page, f"{state}  (held")
        page.click("#step-button")
    trial_text(page, "ended: done")
    assert page.evaluate("window.litSeen") == ["ONE", "TWO", "THREE"]
    # held at each state: the try moved on only when asked
    tries.wait_for(lambda t: t["finished"], BUS_WAIT_S)
    shown = [(t["path"], t["paused"]) for t in tries.messages]
    assert shown == [
        ("ONE", True),
        ("ONE", False),
        ("TWO", True),
        ("TWO", False),
        ("THREE", True),
        ("THREE", False),
        ("", False),
    ], shown
    # the userdata as it changes, in the message and in the page's table
    assert "seen" not in tries.messages[0]["userdata"]
    assert tries.messages[-1]["userdata"]["seen"] == "three"
    assert any(t["changed"] == {"seen": "three"} for t in tries.messages), tries.messages
    page.wait_for_selector('#userdata tr:has-text("seen"):has-text("three")')

    # One state alone: only its command goes out, and its outcome ends the try.
    select_state(page, "TWO")
    watch_lit(page)
    start = tries.mark()
    sent = commands.mark()
    page.click("#run-state-button")
    done = tries.wait_for(lambda t: t["finished"], BUS_WAIT_S, start)
    assert done["outcome"] == "done" and done["behavior"] == "steps", done
    trial_text(page, "ended: done")
    assert page.evaluate("window.litSeen") == ["TWO"]
    assert {t["path"] for t in tries.messages[start:]} == {"TWO", ""}
    commands.wait_for(lambda c: c["args"].get("text") == "two", BUS_WAIT_S, sent)
    texts = [c["args"].get("text") for c in commands.messages[sent:] if c["channel"] == "screen"]
    assert [text for text in texts if text] == ["two"], texts


def test_the_rules_pane_shows_the_verifiers_finding_at_its_line(bench: Bench, page: Any) -> None:
    page.click("#rules-button")
    page.wait_for_selector("#rules-findings li.ok")
    path = (bench.studio.folder / "decisions.dmsl").resolve()
    text = path.read_text().replace("if lowBattery then", "if lowBatery then", 1)
    line = text.splitlines().index("    if lowBatery then") + 1
    page.fill("#rules-text", text)
    finding = page.locator("#rules-findings li.error").first
    finding.wait_for()
    assert finding.get_attribute("data-line") == str(line)
    page.wait_for_selector(f'#rules-gutter div.error[data-line="{line}"]')
    page.click("#rules-save")
    page.wait_for_selector("#rules-status:has-text('not saved')")
    path.write_text(text)
    checked = subprocess.run(
        [sys.executable, "-m", "dms.cli", "rules", "check", str(path)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert checked.returncode == 1
    shown = page.locator("#rules-findings li.error").evaluate_all(
        "items => items.map((item) => item.dataset.text)"
    )
    assert checked.stdout.splitlines() == shown


def test_a_daemon_s_robot_that_is_no_reachy_mini_is_not_posed_by_hand(bench: Bench) -> None:
    """Only the Reachy Mini bridge answers the ask: the page keeps its box off, saying why."""
    status, reply = bench.studio.request("GET", "/api/robot/by-hand")
    assert status == 409 and "not a Reachy Mini" in reply["error"], reply
    from playwright.sync_api import expect

    page = bench.browser.new_page()
    try:
        page.goto(bench.studio.url)
        box = page.locator("#by-hand")
        expect(box).to_be_disabled()
        expect(box.locator("xpath=..")).to_have_attribute("title", re.compile("not a Reachy Mini"))
    finally:
        page.close()
