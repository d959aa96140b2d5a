"""Hot reload: a running daemon takes a behavior file saved into its folder by itself.

A real ``dms run`` over real Zenoh, watching its folder every 0.2 s, never sent SIGHUP
nor ``reload_rules``: a good new version runs on the next request, an invalid one is
reported once on ``dms/errors`` and the running one stays, and a draft (``drafts/``)
changes nothing. Every wait is for a message (the ``reloads`` of ``dms/state``, a
decision, a spoken text).
"""

from __future__ import annotations

import shutil
import time
from pathlib import Path

import pytest
import zenoh

from activities.library import BEHAVIORS_DIR
from tests.integration.harness import Collector, put, running_daemon

pytestmark = pytest.mark.integration

INTRO = (
    "I know some good jokes. Here are a few of them. "
    "Touch my right shoulder if you have had enough."
)
SAVED = "Fresh jokes, saved while I was running."
CONFIG = '[behaviors]\nfolder = "behaviors"\nwatch_s = 0.2\n'
POLLS_S = 2.0
"""The ``dms/state`` messages of this long (2 Hz) span ten polls of the folder."""


def _folder(tmp_path: Path) -> tuple[Path, str]:
    folder = tmp_path / "behaviors"
    shutil.copytree(BEHAVIORS_DIR, folder)
    original = (folder / "jokes.yaml").read_text()
    assert INTRO in original
    return folder, original


class Robot:
    """The collectors of one running daemon, and what a test asks it."""

    def __init__(self, session: zenoh.Session) -> None:
        self.session = session
        self.errors = Collector(session, "robots/mini/dms/errors")
        self.states = Collector(session, "robots/mini/dms/state")
        self.commands = Collector(session, "robots/mini/robot/command")
        self.decisions = Collector(session, "robots/mini/dms/decision")

    def tell_jokes(self) -> str:
        """Start jokes, return its first words, cancel it."""
        mark, said_from = self.decisions.mark(), self.commands.mark()
        put(self.session, "request", {"action": "start", "activity": "jokes", "by": "test"})
        self.decisions.wait_for(
            lambda d: d["action"] == "start" and d["activity"] == "jokes", start=mark
        )
        said = self.commands.wait_for(  # every version of the intro mentions jokes
            lambda c: c["action"] == "say" and "jokes" in c["args"]["text"].lower(),
            start=said_from,
        )
        put(self.session, "request", {"action": "cancel", "activity": "jokes", "by": "test"})
        self.decisions.wait_for(
            lambda d: d["action"] == "cancel" and d["activity"] == "jokes", start=mark
        )
        text = said["args"]["text"]
        assert isinstance(text, str)
        return text

    def reloads_over_polls(self) -> set[int]:
        """The reload counts the states give while the watch polls ten more times."""
        mark = self.states.mark()
        states = self.states.wait_count(mark + int(POLLS_S * 2))
        return {state["reloads"] for state in states[mark:]}


def test_a_saved_behavior_runs_without_sighup_and_an_invalid_one_is_refused_once(
    tmp_path: Path,
) -> None:
    folder, original = _folder(tmp_path)
    jokes = folder / "jokes.yaml"
    with running_daemon(tmp_path, extra_config=CONFIG) as (daemon, session):
        robot = Robot(session)
        assert robot.tell_jokes() == INTRO

        # a good new version, written in place: in force by itself
        jokes.write_text(original.replace(INTRO, SAVED))
        robot.states.wait_for(lambda s: s["reloads"] == 1)
        assert robot.tell_jokes() == SAVED

        # an invalid one (a transition to a missing state): refused, reported once
        jokes.write_text(
            original.replace(INTRO, "Broken jokes.").replace(
                "transitions: {done: PICK}", "transitions: {done: PIK}"
            )
        )
        robot.states.wait_for(lambda s: s["reloads"] == 2)
        report = robot.errors.wait_for(lambda e: e["key"] == "behaviors")
        assert str(jokes) in report["error"] and "PIK" in report["error"]
        assert "keeping the previous behaviors" in report["error"]
        assert robot.tell_jokes() == SAVED
        assert robot.reloads_over_polls() == {2}
        assert robot.errors.messages == [report]

        started = time.monotonic()
        assert daemon.terminate() == 0
        stopped_in = time.monotonic() - started
    assert stopped_in < 2, f"SIGTERM with the watch running took {stopped_in:.1f} s"


def test_a_draft_changes_nothing_and_the_folder_is_still_watched(tmp_path: Path) -> None:
    folder, original = _folder(tmp_path)
    with running_daemon(tmp_path, extra_config=CONFIG) as (_daemon, session):
        robot = Robot(session)
        drafts = folder / "drafts"
        drafts.mkdir()
        (drafts / "jokes.draft.yaml").write_text(original.replace(INTRO, "Draft jokes."))
        (drafts / "quiz.draft.yaml").write_text("name: quiz\nstates: [not, a, behavior\n")
        assert robot.reloads_over_polls() == {0}
        assert robot.tell_jokes() == INTRO
        assert robot.errors.messages == []

        (folder / "jokes.yaml").write_text(original.replace(INTRO, SAVED))
        robot.states.wait_for(lambda s: s["reloads"] == 1)
        assert robot.tell_jokes() == SAVED
