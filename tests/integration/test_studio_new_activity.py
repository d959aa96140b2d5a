"""A designer makes a new activity from nothing, without code, and the robot takes it.

In Debian's Chromium with the mouse and the keyboard only: three states (a greeting, a
question whose answers branch, a song), transitions drawn by dragging each outcome's dot,
the behavior declared an entertainment activity in its form, and saved. Then, from the
outside: ``dms behavior check`` passes the file; a real daemon, connected to the same
studio, reloads its folder and starts it on ``dms request start``; it is in the next
menu under its menu name; and a simulated visitor who likes it gets it proposed by the
decision system's own choice.
"""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from tests.integration.harness import Collector, DaemonProcess, client_session, put
from tests.integration.test_declared_activity import proposed_by_preference
from tests.integration.test_studio import running_studio, shipped_copy
from tests.integration.test_studio_daemon import add
from tests.integration.test_studio_page import drag as drag_over
from tests.integration.viewer_harness import CHROMIUM, CHROMIUM_ARGS, browser_missing

WAIT_MS = 20_000
BUS_WAIT_S = 20.0
DMS = [sys.executable, "-m", "dms.cli"]
ENV = {k: v for k, v in os.environ.items() if not k.startswith("DMS_")}

pytestmark = [
    pytest.mark.integration,
    pytest.mark.skipif(browser_missing() is not None, reason=str(browser_missing())),
]


def dms(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*DMS, *args], capture_output=True, text=True, timeout=120, env=ENV)


def drag(page: Any, source: str, target: str) -> None:
    """Drag from ``source`` to ``target`` with every state in view."""
    page.click("#zoom-fit")
    drag_over(page, source, target)


def port(state: str, outcome: str) -> str:
    return f'.port[data-path="{state}"][data-port="{outcome}"] .hit'


STATE = '.state[data-path="{}"] > rect'
ENDED = ("complete", "fail", "cancel")
END = '.terminal[data-end="done"] rect'


@pytest.fixture
def page(tmp_path: Path) -> Iterator[tuple[Path, DaemonProcess, Any, Any]]:
    """The behaviors folder, a daemon reading it, a Zenoh session, and the studio's page."""
    from playwright.sync_api import sync_playwright

    folder = shipped_copy(tmp_path)
    daemon = DaemonProcess(tmp_path, extra_config=f'\n[behaviors]\nfolder = "{folder}"\n')
    session = client_session(daemon.port)
    try:
        daemon.start(session)
        connect = ("--connect", f"tcp/127.0.0.1:{daemon.port}")
        with running_studio(folder, connect) as studio, sync_playwright() as playwright:
            browser = playwright.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
            try:
                page = browser.new_page(viewport={"width": 1400, "height": 1000})
                errors: list[str] = []
                page.on("pageerror", lambda error: errors.append(str(error)))
                page.set_default_timeout(WAIT_MS)
                page.goto(studio.url)
                page.wait_for_selector("body[data-ready='1']")
                yield folder, daemon, session, page
                assert not errors, errors
            finally:
                browser.close()
        assert daemon.terminate() == 0
    finally:
        daemon.kill()
        session.close()


def test_a_designer_builds_an_activity_from_nothing_and_the_robot_proposes_it(
    page: tuple[Path, DaemonProcess, Any, Any], tmp_path: Path
) -> None:
    folder, daemon, session, p = page
    p.fill("#param-name", "greet_and_ask")
    add(p, "speak", "SPEAK")
    p.fill("#param-text", "Hello {user.name|there}, how nice to see you!")
    add(p, "ask", "ASK")
    p.fill("#param-question", "A song or a story?")
    p.fill("#param-choices", "song\nstory")
    p.check("#param-branch")
    p.fill("#param-timeout_s", "20")
    p.wait_for_selector('.port[data-path="ASK"][data-port="song"]')
    add(p, "speak", "SPEAK_2")
    p.fill("#param-text", "La la la, a little song for you.")
    drag(p, port("SPEAK", "done"), STATE.format("ASK"))
    drag(p, port("ASK", "song"), STATE.format("SPEAK_2"))
    drag(p, port("ASK", "story"), END)
    drag(p, port("ASK", "no_answer"), END)
    drag(p, port("SPEAK_2", "done"), END)
    p.wait_for_selector('.edge[data-from="ASK"][data-outcome="song"][data-to="SPEAK_2"]')

    # Nothing selected: the behavior's own settings, with its Activity form.
    box = p.locator("#canvas").bounding_box()
    p.mouse.click(box["x"] + 12, box["y"] + box["height"] - 12)
    p.wait_for_selector("#activity-declared")
    p.check("#activity-declared")
    p.select_option("#param-manager", '"entertainment"')
    p.fill("#param-menu", "Greet and ask")
    p.fill("#param-expected_s", "60")
    p.fill("#param-hobbies", "music\nreading")
    p.fill("#param-age", "65\n100")
    p.wait_for_selector("#status.good")
    p.click("#save-button")
    p.wait_for_selector("body[data-saved='saved']")

    saved = folder / "greet_and_ask.yaml"
    checked = dms("behavior", "check", str(saved))
    assert checked.returncode == 0, checked.stdout + checked.stderr + saved.read_text()
    text = saved.read_text()
    assert "manager: entertainment" in text and "song: SPEAK_2" in text, text

    # The daemon takes it on a reload and starts it by name.
    connect = ("--connect", f"tcp/127.0.0.1:{daemon.port}")
    assert dms("request", "reload", *connect).returncode == 0
    decisions = Collector(session, "robots/mini/dms/decision")
    commands = Collector(session, "robots/mini/robot/command")
    started = dms("request", "start", "greet_and_ask", *connect)
    assert started.returncode == 0, started.stderr
    assert " start    greet_and_ask [user_request" in started.stdout, started.stdout
    commands.wait_for(lambda c: "how nice to see you" in c["args"].get("text", ""), BUS_WAIT_S)
    asked = commands.wait_for(lambda c: c["args"].get("text") == "A song or a story?", BUS_WAIT_S)
    assert asked["action"] == "say", asked
    put(session, "perception/speech", {"text": "a song please", "confidence": 0.9})
    commands.wait_for(lambda c: c["args"].get("text") == "La la la, a little song for you.")
    done = decisions.wait_for(
        lambda d: d["activity"] == "greet_and_ask" and d["action"] in ENDED,
        BUS_WAIT_S,
    )
    assert done["action"] == "complete", done

    # In the next menu, under its menu name.
    states = Collector(session, "robots/mini/dms/state")
    put(session, "perception/user", {"present": True, "user_id": "ann", "ready": True})
    states.wait_for(lambda s: (s["user"] or {}).get("id") == "ann", BUS_WAIT_S)
    put(session, "request", {"action": "start", "activity": "menu", "by": "ann"})
    shown = commands.wait_for(
        lambda c: c["channel"] == "screen" and "greet_and_ask" in c["args"].get("choices", []),
        BUS_WAIT_S,
    )
    assert shown["args"]["labels"] == {"greet_and_ask": "Greet and ask"}, shown
    put(session, "perception/user", {"present": False})
    states.wait_for(lambda s: s["user"] is None, BUS_WAIT_S)

    # A simulated visitor who likes it gets it proposed by the robot's own choice.
    by_preference = proposed_by_preference(tmp_path, folder, "greet_and_ask")
    assert "greet_and_ask" in by_preference, by_preference
