"""A behavior declared an activity, from the outside: a behaviors folder with one more
file, a real daemon and the ``dms`` commands a designer and an operator type.

Declared, it is started by ``dms request start`` and by a request over Zenoh, offered in
the menu with its menu name, chosen by the preference chooser for a visitor who likes it
(a scenario on the simulator), and removing it leaves a daemon that starts and chooses on
the rows that still name it.
"""

from __future__ import annotations

import csv
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from activities.library import BEHAVIORS_DIR
from tests.integration.harness import Collector, DaemonProcess, client_session, put

pytestmark = pytest.mark.integration

DMS = [sys.executable, "-m", "dms.cli"]
ENV = {k: v for k, v in os.environ.items() if not k.startswith("DMS_")}

GREET_AND_ASK = """\
name: greet_and_ask
description: Greets the user and asks whether they would like a song or a story.
activity:
  manager: entertainment
  menu: Greet and ask
  picture: greet.png
  expected_s: 60
  features: {hobbies: [music, reading], age: [65, 100]}
outcomes: [done]
states:
  GREET:
    speak: {text: "Hello {user.name|there}, how nice to see you!"}
    transitions: {done: ASK}
  ASK:
    ask: {question: "A song or a story?", choices: [song, story], branch: true, timeout_s: 20}
    transitions: {song: SING, story: TELL, no_answer: done}
  SING:
    speak: {text: "La la la, a little song for you."}
    transitions: {done: done}
  TELL:
    speak: {text: "Once upon a time, a robot made a friend."}
    transitions: {done: done}
"""

ANN_READY = {"present": True, "user_id": "ann", "ready": True, "engagement": 0.8}


def dms(*args: str, timeout: float = 120.0) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*DMS, *args], capture_output=True, text=True, timeout=timeout, env=ENV)


def behaviors_folder(tmp: Path, declared: str | None = GREET_AND_ASK) -> Path:
    """The shipped behaviors, plus ``greet_and_ask.yaml`` when ``declared``."""
    folder = tmp / "behaviors"
    shutil.copytree(BEHAVIORS_DIR, folder, dirs_exist_ok=True)
    if declared is not None:
        (folder / "greet_and_ask.yaml").write_text(declared, encoding="utf-8")
    return folder


def daemon_for(tmp: Path, folder: Path) -> DaemonProcess:
    return DaemonProcess(tmp, extra_config=f'[behaviors]\nfolder = "{folder}"\nwatch_s = 0\n')


def test_check_says_what_is_wrong_with_a_declaration_one_line_each(tmp_path: Path) -> None:
    folder = behaviors_folder(tmp_path)
    bad = GREET_AND_ASK.replace("manager: entertainment", "manager: games").replace(
        "hobbies: [music, reading]", "hobby: [music]"
    )
    (folder / "greet_and_ask.yaml").write_text(bad, encoding="utf-8")
    clash = GREET_AND_ASK.replace("name: greet_and_ask", "name: bingo")
    (folder / "bingo.yaml").write_text(clash, encoding="utf-8")
    checked = dms("behavior", "check", str(folder))
    assert checked.returncode == 1
    problems = [line for line in checked.stdout.splitlines() if not line.endswith(": ok")]
    assert problems == [
        f"{folder}/bingo.yaml:3: activity: 'bingo' is a shipped activity: rename the behavior "
        "to declare a new one (a behavior named for a shipped activity replaces its steps "
        "and needs no declaration)",
        f"{folder}/greet_and_ask.yaml:4: activity: manager 'games' is not one of "
        "entertainment, cognitive, social, relax: write one of them",
        f"{folder}/greet_and_ask.yaml:8: activity: feature 'hobby' is not one the preference "
        "model learns from: did you mean hobbies? use one of age, sex, education, "
        "occupation, hobbies, lives_alone",
    ], checked.stdout


def _start_decision(decisions: Collector, name: str, start: int) -> dict[str, Any]:
    return decisions.wait_for(
        lambda d: d["action"] == "start" and d["activity"] == name, start=start, timeout=20
    )


def test_a_declared_activity_starts_on_request_is_offered_and_survives_its_removal(
    tmp_path: Path,
) -> None:
    folder = behaviors_folder(tmp_path)
    daemon = daemon_for(tmp_path, folder)
    session = client_session(daemon.port)
    try:
        decisions = Collector(session, "robots/mini/dms/decision")
        commands = Collector(session, "robots/mini/robot/command")
        daemon.start(session)
        connect = ("--connect", f"tcp/127.0.0.1:{daemon.port}")
        started = dms("request", "start", "greet_and_ask", *connect)
        assert started.returncode == 0, started.stderr
        assert " start    greet_and_ask [user_request" in started.stdout
        typo = dms("request", "start", "greet_and_asc", *connect)
        assert typo.returncode == 1
        assert "unknown activity 'greet_and_asc'; did you mean greet_and_ask?" in typo.stderr
        # Ann asks for it over Zenoh, opens the menu
        states = Collector(session, "robots/mini/dms/state")
        put(session, "perception/user", ANN_READY)
        states.wait_for(lambda s: (s["user"] or {}).get("id") == "ann")  # her session began
        mark = decisions.mark()
        put(session, "request", {"action": "start", "activity": "menu", "by": "ann"})
        _start_decision(decisions, "menu", mark)
        shown = commands.wait_for(
            lambda c: c["channel"] == "screen" and "greet_and_ask" in c["args"].get("choices", [])
        )
        assert shown["args"]["labels"] == {"greet_and_ask": "Greet and ask"}
        assert shown["args"]["pictures"] == {"greet_and_ask": "greet.png"}
        mark = decisions.mark()
        put(session, "perception/screen", {"choice": "greet_and_ask"})
        chosen = _start_decision(decisions, "greet_and_ask", mark)
        assert (chosen["reason"], chosen["manager"]) == ("user_choice", "entertainment")
        # she stops it herself: her profile keeps a row that names it
        mark = decisions.mark()  # the shoulder, then "stop"
        put(session, "perception/touch", {"part": "right_shoulder", "kind": "tap"})
        decisions.wait_for(lambda d: d["action"] == "ask", start=mark)
        put(session, "perception/screen", {"choice": "stop"})
        decisions.wait_for(lambda d: d["action"] == "cancel" and d["activity"] == "greet_and_ask")
        seen = states.mark()
        put(session, "perception/user", {"present": False})
        states.wait_for(lambda s: s["user"] is None, start=seen)  # her session ended
        assert daemon.terminate() == 0  # flushes the store
        assert (
            "greet_and_ask"
            in json.loads(dms("users", "show", "ann", "--db", daemon.db).stdout)["scores"]
        )
        # removed: the daemon starts on the rows that name it, and chooses among the others
        (folder / "greet_and_ask.yaml").unlink()
        errors = Collector(session, "robots/mini/dms/errors")
        mark = decisions.mark()
        daemon.start(session)
        put(session, "perception/user", ANN_READY)
        chosen = decisions.wait_for(
            lambda d: d["action"] == "start" and d["reason"] in ("preference", "user_choice"),
            start=mark,
            timeout=30,
        )
        assert chosen["activity"] != "greet_and_ask"
        refused = dms("request", "start", "greet_and_ask", *connect)
        assert refused.returncode == 1
        assert "refused: unknown activity 'greet_and_ask'" in refused.stderr
        assert not [e for e in errors.messages if str(e.get("key", "")).startswith("tick")]
        assert daemon.terminate() == 0
    finally:
        daemon.kill()
        session.close()


FAN = """\
name: fan
description: Likes being greeted and asked, little else.
user_id: fan
features: {name: Fay, age: 74, sex: female, hobbies: music}
preferences:
  {quiz: 0.1, jokes: 0.1, multimedia: 0.1, dance: 0.1, weather: 0.1, news: 0.1, bingo: 0.1,
   sayings: 0.1, declared: {greet_and_ask: 0.95}}
proactivity: low
speech: {error_rate: 0.0, answer_delay_s: [0.8, 1.6], no_answer_rate: 0.0, screen_rate: 0.6}
patience: {dislike_below: 0.35, stop_after_s: [4, 8], continue_rate: 0.0, max_touches: 50}
arrive_after_s: [0.5, 1.5]
"""


def proposed_by_preference(tmp: Path, folder: Path, activity: str) -> list[str]:
    """Run a 30-minute scenario on ``folder`` with a visitor who likes ``activity`` (0.95)
    and little else, rating every activity; the activities the robot chose for her."""
    (tmp / "fan.yaml").write_text(FAN.replace("greet_and_ask", activity), encoding="utf-8")
    scenario = tmp / "declared.yaml"
    scenario.write_text(
        "name: declared_preference\nseed: 5\nduration_s: 1800\n"
        f"settings: {{behaviors: {{folder: {folder}}}, controller: {{session_questions: 0, "
        "feedback_probability: 1.0, user_initiative: {low: 0.0}}}\n"
        f"timeline:\n  - {{at: 0, visitor: {{persona: {tmp / 'fan.yaml'}}}}}\n"
        f"expect:\n  - {{decision: {{action: start, activity: {activity}, reason: preference,"
        " chosen_by: robot}}\n",
        encoding="utf-8",
    )
    ran = dms("sim", "run", str(scenario), "--json")
    assert ran.returncode == 0, ran.stdout[-2000:] + ran.stderr
    decisions = json.loads(ran.stdout)["decisions"]
    return [
        d["activity"] for d in decisions if d["action"] == "start" and d["reason"] == "preference"
    ]


def test_a_visitor_who_likes_it_gets_it_proposed_by_the_preference_chooser(
    tmp_path: Path,
) -> None:
    folder = behaviors_folder(tmp_path)
    by_preference = proposed_by_preference(tmp_path, folder, "greet_and_ask")
    assert "greet_and_ask" in by_preference
    late = by_preference[len(by_preference) // 2 :]
    # learnt from her stops and ratings: the robot's favourite pick for her, once it knows
    assert max(set(late), key=late.count) == "greet_and_ask", late


def test_an_activity_declared_while_the_daemon_runs_is_in_force_after_a_reload(
    tmp_path: Path,
) -> None:
    folder = behaviors_folder(tmp_path, declared=None)
    daemon = daemon_for(tmp_path, folder)
    session = client_session(daemon.port)
    try:
        daemon.start(session)
        connect = ("--connect", f"tcp/127.0.0.1:{daemon.port}")
        before = dms("request", "start", "greet_and_ask", *connect)
        assert before.returncode == 1
        assert "refused: unknown activity 'greet_and_ask'" in before.stderr, before.stderr
        (folder / "greet_and_ask.yaml").write_text(GREET_AND_ASK, encoding="utf-8")
        reloaded = dms("request", "reload", *connect)
        assert reloaded.returncode == 0, reloaded.stderr
        started = dms("request", "start", "greet_and_ask", *connect)
        assert started.returncode == 0, started.stderr
        assert " start    greet_and_ask [user_request" in started.stdout
        assert daemon.terminate() == 0
    finally:
        daemon.kill()
        session.close()


def test_a_study_on_a_folder_that_declares_it_counts_it_like_any_other(tmp_path: Path) -> None:
    folder = behaviors_folder(tmp_path)
    config = tmp_path / "dms.toml"
    config.write_text(f'[behaviors]\nfolder = "{folder}"\n', encoding="utf-8")
    out = tmp_path / "study"
    ran = dms("sim", "study", "--sessions", "6", "--config", str(config), "--out", str(out))
    assert ran.returncode == 0, ran.stdout[-2000:] + ran.stderr
    with (out / "decisions.csv").open(encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    chosen = [r for r in rows if r["reason"] == "preference"]
    ranked = [json.loads(r["why"])["choice"]["ranking"] for r in chosen]
    assert any("greet_and_ask" in ranking for ranking in ranked)  # ranked among the others
    started = [r for r in rows if r["action"] == "start" and r["activity"] == "greet_and_ask"]
    assert started and all(r["manager"] == "entertainment" for r in started)
    with (out / "events.csv").open(encoding="utf-8") as handle:
        events = [e for e in csv.DictReader(handle) if e["activity"] == "greet_and_ask"]
    assert {e["event"] for e in events} >= {"started"}, events
