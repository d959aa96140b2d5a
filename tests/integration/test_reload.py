"""Reloading a running daemon: rules and behaviors, on SIGHUP and on ``reload_rules``.

A real ``dms run`` over real Zenoh. An invalid new version is reported once on
``dms/errors`` and the previous one keeps deciding; a valid one takes effect for the
next decision or the next activity. Every wait is for a message.
"""

from __future__ import annotations

import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest
import zenoh

from activities.library import BEHAVIORS_DIR
from tests.integration.harness import (
    Collector,
    DaemonProcess,
    free_port,
    put,
    query,
    running_daemon,
)

pytestmark = pytest.mark.integration

ANN_READY = {"present": True, "user_id": "ann", "ready": True, "engagement": 0.8}

RULES = """\
component ChooseMode [ activate "autonomous" ]
component ChooseEntertainment [ activate "{activity}" ]
"""


def _rules(activity: str) -> str:
    return RULES.replace("{activity}", activity)


def _robot_pick(decisions: Collector, mark: int) -> dict[str, Any]:
    """The next activity the robot starts by itself (a rule or its preferences)."""
    return decisions.wait_for(
        lambda d: d["action"] == "start" and d["reason"] == "preference", start=mark
    )


def _cancel_and_pick(session: zenoh.Session, decisions: Collector, activity: str) -> str:
    """Cancel the running activity; the detail of the robot's next pick."""
    mark = decisions.mark()
    put(session, "request", {"action": "cancel", "activity": activity, "by": "test"})
    detail = _robot_pick(decisions, mark)["detail"]
    assert isinstance(detail, str)
    return detail


def _hup(daemon: DaemonProcess) -> None:
    assert daemon.proc is not None
    daemon.proc.send_signal(signal.SIGHUP)


def test_rules_reload_keeps_old_rules_on_error_and_takes_new_ones(tmp_path: Path) -> None:
    rules = tmp_path / "decisions.dmsl"
    rules.write_text(_rules("jokes"))
    config = '[rules]\nfiles = ["decisions.dmsl"]\n'
    with running_daemon(tmp_path, extra_config=config) as (daemon, session):
        decisions = Collector(session, "robots/mini/dms/decision")
        errors = Collector(session, "robots/mini/dms/errors")
        put(session, "perception/user", ANN_READY)
        assert _robot_pick(decisions, 0)["detail"] == "rule ChooseEntertainment -> jokes"

        # an invalid version (a syntax error): reported once, the old rules decide
        states = Collector(session, "robots/mini/dms/state")
        rules.write_text(_rules("news").replace("activate", "activat", 1))
        _hup(daemon)
        states.wait_for(lambda s: s["reloads"] == 1)
        report = errors.wait_for(lambda e: e["key"] == "rules")
        assert str(rules) in report["error"] and "syntax error" in report["error"]
        assert _cancel_and_pick(session, decisions, "jokes") == "rule ChooseEntertainment -> jokes"
        assert [e for e in errors.messages if e["key"] == "rules"] == [report]

        # a valid version through the request: the next decision follows it
        rules.write_text(_rules("news"))
        put(session, "request", {"action": "reload_rules", "by": "test"})
        states.wait_for(lambda s: s["reloads"] == 2)
        assert _cancel_and_pick(session, decisions, "jokes") == "rule ChooseEntertainment -> news"
        assert len(errors.messages) == 1


def test_behaviors_reload_keeps_old_version_on_error_and_takes_new_one(tmp_path: Path) -> None:
    folder = tmp_path / "behaviors"
    shutil.copytree(BEHAVIORS_DIR, folder)
    jokes = folder / "jokes.yaml"
    original = jokes.read_text()
    intro = (
        "I know some good jokes. Here are a few of them. "
        "Touch my right shoulder if you have had enough."
    )
    assert intro in original
    with running_daemon(tmp_path, extra_config='[behaviors]\nfolder = "behaviors"\n') as (
        daemon,
        session,
    ):
        errors = Collector(session, "robots/mini/dms/errors")
        commands = Collector(session, "robots/mini/robot/command")
        decisions = Collector(session, "robots/mini/dms/decision")

        def tell_jokes() -> str:
            """Start jokes, return its first words, cancel it."""
            mark, said_from = decisions.mark(), commands.mark()
            put(session, "request", {"action": "start", "activity": "jokes", "by": "test"})
            decisions.wait_for(
                lambda d: d["action"] == "start" and d["activity"] == "jokes", start=mark
            )
            said = commands.wait_for(  # both versions of the intro mention jokes
                lambda c: c["action"] == "say" and "jokes" in c["args"]["text"].lower(),
                start=said_from,
            )
            put(session, "request", {"action": "cancel", "activity": "jokes", "by": "test"})
            decisions.wait_for(
                lambda d: d["action"] == "cancel" and d["activity"] == "jokes", start=mark
            )
            text = said["args"]["text"]
            assert isinstance(text, str)
            return text

        assert tell_jokes() == intro

        # an invalid version (a transition to a missing state): refused, old one kept
        states = Collector(session, "robots/mini/dms/state")
        jokes.write_text(original.replace("transitions: {done: PICK}", "transitions: {done: PIK}"))
        _hup(daemon)
        states.wait_for(lambda s: s["reloads"] == 1)
        report = errors.wait_for(lambda e: e["key"] == "behaviors")
        assert str(jokes) in report["error"] and "PIK" in report["error"]
        assert "\n" not in report["error"]
        assert tell_jokes() == intro

        # a valid version: the next jokes activity says the new text
        jokes.write_text(original.replace(intro, "Fresh jokes, just written."))
        # the reload runs in the background; the state says when it is in force
        put(session, "request", {"action": "reload_rules", "by": "test"})
        states.wait_for(lambda s: s["reloads"] == 2)
        assert tell_jokes() == "Fresh jokes, just written."
        assert len(errors.messages) == 1


def test_behavior_queryable_answers_with_the_running_structure(tmp_path: Path) -> None:
    with running_daemon(tmp_path) as (_daemon, session):
        decisions = Collector(session, "robots/mini/dms/decision")
        commands = Collector(session, "robots/mini/robot/command")
        put(session, "request", {"action": "start", "activity": "jokes", "by": "test"})
        decisions.wait_for(lambda d: d["action"] == "start" and d["activity"] == "jokes")
        commands.wait_for(lambda c: c["action"] == "say" and "jokes" in c["args"]["text"])
        ((ok, answer),) = query(session, "dms/behavior")
        assert ok and answer["activity"] == "jokes"
        structure = answer["structure"]
        assert structure["name"] == "jokes" and structure["status"] == "running"
        assert structure["active_path"].startswith(("INTRO", "PICK", "TELL"))
        root = structure["root"]
        assert root["kind"] == "state_machine" and root["transitions"]["INTRO"] == {"done": "PICK"}
        assert {"INTRO", "PICK", "TELL", "END", "SETUP", "PUNCHLINE"} <= _state_names(root)
        active = [s["name"] for s in root["states"] if s["active"]]
        assert active == [structure["active_path"].split("/")[0]]


def _state_names(node: dict[str, Any]) -> set[str]:
    names = {str(node.get("name"))}
    for child in node.get("states") or []:
        names |= _state_names(child)
    return names


def _rules_bomb(activity: str) -> str:
    """Valid rules whose ``def``s each use the previous one twice: two to the fortieth
    terms written out, refused by the verifier's budget at the first ``def`` over it."""
    lines = ["def d0 params.user.age > 3"]
    lines += [f"def d{i} d{i - 1} and not d{i - 1}" for i in range(1, 40)]
    return (
        "\n".join(lines)
        + "\n"
        + _rules(activity).replace('[ activate "', '[ if d39 then activate "', 1)
    )


def test_a_rules_bomb_is_refused_on_reload_and_sigterm_during_a_reload_is_prompt(
    tmp_path: Path,
) -> None:
    rules = tmp_path / "decisions.dmsl"
    rules.write_text(_rules("jokes"))
    config = '[rules]\nfiles = ["decisions.dmsl"]\n'
    with running_daemon(tmp_path, extra_config=config) as (daemon, session):
        decisions = Collector(session, "robots/mini/dms/decision")
        errors = Collector(session, "robots/mini/dms/errors")
        states = Collector(session, "robots/mini/dms/state")
        put(session, "perception/user", ANN_READY)
        assert _robot_pick(decisions, 0)["detail"] == "rule ChooseEntertainment -> jokes"

        rules.write_text(_rules_bomb("news"))
        started = time.monotonic()
        _hup(daemon)
        report = errors.wait_for(lambda e: e["key"] == "rules", timeout=20)
        assert time.monotonic() - started < 5, "the verifier's budget bounds the reload"
        assert f"{rules}:12:1: too complex to verify here" in report["error"], report
        states.wait_for(lambda s: s["reloads"] == 1)
        assert _cancel_and_pick(session, decisions, "jokes") == "rule ChooseEntertainment -> jokes"

        _hup(daemon)  # and stop at once, the reload under way
        assert daemon.proc is not None
        started = time.monotonic()
        code = daemon.terminate()
        stopped_in = time.monotonic() - started
    assert code == 0
    assert stopped_in < 2, f"SIGTERM during a reload took {stopped_in:.1f} s"


def test_an_alias_bomb_in_a_behavior_is_refused_on_reload(tmp_path: Path) -> None:
    folder = tmp_path / "behaviors"
    shutil.copytree(BEHAVIORS_DIR, folder)
    with running_daemon(tmp_path, extra_config='[behaviors]\nfolder = "behaviors"\n') as (
        daemon,
        session,
    ):
        errors = Collector(session, "robots/mini/dms/errors")
        states = Collector(session, "robots/mini/dms/state")
        lines = ["name: bomb", "outcomes: [done]", "userdata:", "  a0: &a0 [x, x, x, x, x, x]"]
        lines += [f"  a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * 9)}]" for i in range(1, 9)]
        (folder / "bomb.yaml").write_text("\n".join([*lines, "states: {S: {wait: {seconds: 1}}}"]))
        started = time.monotonic()
        _hup(daemon)
        report = errors.wait_for(lambda e: e["key"] == "behaviors", timeout=20)
        assert time.monotonic() - started < 5
        assert str(folder / "bomb.yaml") in report["error"]
        assert (
            "aliases written out add more than" in report["error"] and "\n" not in report["error"]
        )
        states.wait_for(lambda s: s["reloads"] == 1)
        assert daemon.terminate() == 0


def test_a_daemon_started_with_a_rules_bomb_refuses_it_in_one_line(tmp_path: Path) -> None:
    (tmp_path / "decisions.dmsl").write_text(_rules_bomb("news"))
    config = tmp_path / "dms.toml"
    config.write_text('[rules]\nfiles = ["decisions.dmsl"]\n')
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "dms.cli",
            "run",
            "--config",
            str(config),
            "--db",
            f"sqlite:///{tmp_path / 'dms.db'}",
            "--listen",
            f"tcp/127.0.0.1:{free_port()}",
        ],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 1
    assert done.stderr.startswith("dms: rules: "), done.stderr
    assert "too complex to verify here" in done.stderr
