"""A running daemon refuses, on reload, a behavior that ``dms behavior check`` refuses.

A real ``dms run`` over real Zenoh: a misspelled placeholder is reported once on
``dms/errors`` with its file, line and the right name, and the previous version of the
behavior keeps running. Every wait is for a message.
"""

from __future__ import annotations

import shutil
import signal
from pathlib import Path

import pytest

from activities.library import BEHAVIORS_DIR
from tests.integration.harness import Collector, put, running_daemon

pytestmark = pytest.mark.integration

INTRO = (
    "I know some good jokes. Here are a few of them. "
    "Touch my right shoulder if you have had enough."
)


def test_a_reload_refuses_a_misspelled_placeholder_and_keeps_the_old_behavior(
    tmp_path: Path,
) -> None:
    folder = tmp_path / "behaviors"
    shutil.copytree(BEHAVIORS_DIR, folder)
    jokes = folder / "jokes.yaml"
    original = jokes.read_text()
    assert INTRO in original and original.count("{joke.punchline}") == 1
    with running_daemon(tmp_path, extra_config='[behaviors]\nfolder = "behaviors"\n') as (
        daemon,
        session,
    ):
        errors = Collector(session, "robots/mini/dms/errors")
        states = Collector(session, "robots/mini/dms/state")
        commands = Collector(session, "robots/mini/robot/command")
        decisions = Collector(session, "robots/mini/dms/decision")

        # a new intro, and a punchline the robot would say as an empty sentence
        jokes.write_text(
            original.replace(INTRO, "New jokes!").replace("{joke.punchline}", "{joke.punchlin}")
        )
        assert daemon.proc is not None
        daemon.proc.send_signal(signal.SIGHUP)
        states.wait_for(lambda s: s["reloads"] == 1)
        report = errors.wait_for(lambda e: e["key"] == "behaviors")
        line = original[: original.index("{joke.punchline}")].count("\n") + 1
        assert report["error"].startswith(f"{jokes}:{line}: state TELL/JOKE/PUNCHLINE: ")
        assert "did you mean {joke.punchline}?" in report["error"]
        assert "keeping the previous behaviors" in report["error"]

        said_from = commands.mark()
        put(session, "request", {"action": "start", "activity": "jokes", "by": "test"})
        decisions.wait_for(lambda d: d["action"] == "start" and d["activity"] == "jokes")
        said = commands.wait_for(  # both intros mention jokes
            lambda c: c["action"] == "say" and "jokes" in c["args"]["text"].lower(),
            start=said_from,
        )
        assert said["args"]["text"] == INTRO  # the previous version runs
