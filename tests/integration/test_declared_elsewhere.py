"""A declared activity where the daemon is not the one who reads it: ``dms agenda add``
on the database file, a scenario file for ``dms sim run``, a drive of the ``[motivation]``
table, a reminder over one that may not be paused, and ``dms behavior check`` on the
names a text and a medium may use.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

import pytest

from tests.integration.harness import Collector, DaemonProcess, client_session, put
from tests.integration.test_declared_activity import ANN_READY, GREET_AND_ASK, behaviors_folder

pytestmark = pytest.mark.integration

DMS = [sys.executable, "-m", "dms.cli"]
ENV = {k: v for k, v in os.environ.items() if not k.startswith("DMS_")}

NAP = """\
name: nap
description: A short rest for the robot, with its eyes closed.
activity:
  manager: relax
  menu: A nap
outcomes: [done]
states:
  DOZE:
    show: {face: closed_eyes}
    transitions: {done: done}
"""


def dms(*args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [*DMS, *args], capture_output=True, text=True, timeout=180, env={**ENV, **(env or {})}
    )


def _met_ann(tmp: Path, folder: Path) -> DaemonProcess:
    """A daemon run once with the folder, long enough to meet Ann (the agenda takes items
    for users the robot has met), then stopped: its database holds her profile."""
    daemon = DaemonProcess(tmp, extra_config=f'[behaviors]\nfolder = "{folder}"\nwatch_s = 0\n')
    session = client_session(daemon.port)
    try:
        daemon.start(session)
        states = Collector(session, "robots/mini/dms/state")
        put(session, "perception/user", ANN_READY)
        states.wait_for(lambda s: (s["user"] or {}).get("id") == "ann")
        seen = states.mark()
        put(session, "perception/user", {"present": False})
        states.wait_for(lambda s: s["user"] is None, start=seen)
        assert daemon.terminate() == 0
    finally:
        daemon.kill()
        session.close()
    return daemon


def test_agenda_add_takes_a_declared_activity_and_the_daemon_runs_it_when_due(
    tmp_path: Path,
) -> None:
    folder = behaviors_folder(tmp_path)
    daemon = _met_ann(tmp_path, folder)
    at = (datetime.now(UTC) + timedelta(seconds=2)).replace(tzinfo=None).isoformat()
    event = ("agenda", "add", "--user", "ann", "--event", "greet_and_ask", "--at", at)
    # without the folder the command knows only the shipped activities, and says so
    shipped = dms(*event, "--db", daemon.db)
    assert shipped.returncode == 1
    assert shipped.stderr.startswith("dms: unknown activity 'greet_and_ask'"), shipped.stderr
    assert len(shipped.stderr.splitlines()) == 1
    typo = dms(
        *event[:5], "greet_and_asc", *event[6:], "--db", daemon.db, "--behaviors", str(folder)
    )
    assert typo.returncode == 1
    assert typo.stderr == "dms: unknown activity 'greet_and_asc'; did you mean greet_and_ask?\n"
    # the folder of the daemon's configuration, as dms run reads it
    added = dms(*event, "--db", daemon.db, "--config", str(daemon.config), "--json")
    assert added.returncode == 0, added.stderr
    item = json.loads(added.stdout)["item"]
    assert (item["kind"], item["activity"]) == ("event", "greet_and_ask")
    # the same folder given by DMS_BEHAVIORS__FOLDER, as the daemon would take it
    again = dms(*event, "--db", daemon.db, env={"DMS_BEHAVIORS__FOLDER": str(folder)})
    assert again.returncode == 0, again.stderr
    listed = json.loads(dms("agenda", "list", "--db", daemon.db, "--json").stdout)["items"]
    assert [i["activity"] for i in listed] == ["greet_and_ask", "greet_and_ask"]
    # a real daemon with that folder runs it for Ann when it falls due
    session = client_session(daemon.port)
    try:
        decisions = Collector(session, "robots/mini/dms/decision")
        daemon.start(session)
        put(session, "perception/user", ANN_READY)
        run = decisions.wait_for(
            lambda d: d["action"] == "start" and d["activity"] == "greet_and_ask", timeout=30
        )
        assert (run["reason"], run["chosen_by"]) == ("agenda", "agenda")
        assert daemon.terminate() == 0
    finally:
        daemon.kill()
        session.close()


def _scenario(tmp: Path, folder: Path, body: str) -> Path:
    path = tmp / "scenario.yaml"
    path.write_text(
        f"name: declared\nseed: 2\nduration_s: 40\nsettings: {{behaviors: {{folder: {folder}}}, "
        "controller: {session_questions: 0, question_every: 0, feedback_probability: 0}}\n" + body,
        encoding="utf-8",
    )
    return path


REMINDED = """\
timeline:
  - {at: 0, arrive: {user: ann}}
  - {at: 2, request: {action: start, activity: greet_and_ask, by: ann}}
  - {at: 3, agenda: {kind: reminder, user: ann, in_s: 5, text: "Time for your pills."}}
expect:
  - {decision: {action: start, activity: greet_and_ask, reason: user_request}, within: [2, 3]}
"""


def _run(path: Path) -> list[dict[str, Any]]:
    ran = dms("sim", "run", str(path), "--json")
    assert ran.returncode == 0, ran.stdout[-2000:] + ran.stderr
    decisions: list[dict[str, Any]] = json.loads(ran.stdout)["decisions"]
    return decisions


REMINDER = '  - {at: 3, agenda: {kind: reminder, user: ann, in_s: 5, text: "Time for your pills."}}'


def _unpausable(tmp: Path, instead_of_the_reminder: str | None = None) -> list[dict[str, Any]]:
    """The decisions of REMINDED with greet_and_ask declared not pausable, and the
    reminder replaced by ``instead_of_the_reminder`` when given."""
    stiff = GREET_AND_ASK.replace("expected_s: 60", "expected_s: 60\n  pausable: false")
    folder = behaviors_folder(tmp, declared=stiff)
    body = REMINDED
    if instead_of_the_reminder is not None:
        body = REMINDED.replace(REMINDER, instead_of_the_reminder)
    return _run(_scenario(tmp, folder, body))


def _around_the_reminder(decisions: list[dict[str, Any]]) -> list[tuple[str, str, str]]:
    return [
        (d["action"], d["activity"], d["reason"])
        for d in decisions
        if d["activity"] in ("greet_and_ask", "notification")
    ]


def test_a_reminder_stops_a_declared_activity_that_may_not_be_paused_and_says_so(
    tmp_path: Path,
) -> None:
    decisions = _unpausable(tmp_path)
    assert _around_the_reminder(decisions)[:3] == [
        ("start", "greet_and_ask", "user_request"),
        ("cancel", "greet_and_ask", "agenda"),
        ("start", "notification", "agenda"),
    ], decisions
    cancel = next(
        d for d in decisions if d["action"] == "cancel" and d["activity"] == "greet_and_ask"
    )
    assert cancel["detail"] == "reminder 1; it cannot be paused: stopped", cancel
    assert not [d for d in decisions if d["action"] in ("pause", "resume")], decisions


def test_a_reminder_pauses_a_declared_activity_that_may_be_and_resumes_it(
    tmp_path: Path,
) -> None:
    folder = behaviors_folder(tmp_path)
    decisions = _run(_scenario(tmp_path, folder, REMINDED))
    actions = _around_the_reminder(decisions)
    assert actions[:3] == [
        ("start", "greet_and_ask", "user_request"),
        ("pause", "greet_and_ask", "agenda"),
        ("start", "notification", "agenda"),
    ], decisions
    assert ("resume", "greet_and_ask", "agenda") in actions


def test_a_scenario_names_a_declared_activity_of_its_folder_and_a_typo_is_one_line(
    tmp_path: Path,
) -> None:
    folder = behaviors_folder(tmp_path)
    decisions = _run(_scenario(tmp_path, folder, REMINDED))
    started = [d["activity"] for d in decisions if d["action"] == "start"]
    assert "greet_and_ask" in started, decisions
    typo = _scenario(
        tmp_path,
        folder,
        REMINDED.replace("activity: greet_and_ask, by", "activity: greet_and_asc, by"),
    )
    ran = dms("sim", "run", str(typo))
    assert ran.returncode == 1
    line = ran.stderr.strip()
    assert line.startswith(f"dms: {typo}:"), ran.stderr
    assert line.endswith("unknown activity 'greet_and_asc'; did you mean greet_and_ask?"), line
    assert len(ran.stderr.splitlines()) == 1


def test_a_drive_may_name_a_declared_relax_activity(tmp_path: Path) -> None:
    folder = behaviors_folder(tmp_path, declared=None)
    (folder / "nap.yaml").write_text(NAP, encoding="utf-8")
    config = tmp_path / "dms.toml"
    config.write_text(
        f'[behaviors]\nfolder = "{folder}"\n\n[motivation.drives.rest]\nbehavior = "nap"\n',
        encoding="utf-8",
    )
    shown = dms("motivation", "show", "--config", str(config))
    assert shown.returncode == 0, shown.stderr
    assert "nap" in shown.stdout
    # the daemon, on the simulator: the motivation's rest drive runs the declared nap
    path = tmp_path / "rest.yaml"
    path.write_text(
        f"name: rest\nseed: 1\nduration_s: 1800\nsettings: {{behaviors: {{folder: {folder}}}, "
        "motivation: {drives: {rest: {behavior: nap, rate_per_hour: 100, threshold: 20}}}}\n"
        "expect:\n  - {decision: {action: start, activity: nap, reason: motivation}}\n",
        encoding="utf-8",
    )
    _run(path)
    # a behavior that is no activity is still one line, with the nearest name
    typo = config.read_text().replace('behavior = "nap"', 'behavior = "nape"')
    config.write_text(typo, encoding="utf-8")
    refused = dms("motivation", "show", "--config", str(config))
    assert refused.returncode == 1
    assert refused.stderr == (
        f"dms: {config}: motivation.drives.rest.behavior: unknown behavior 'nape'; "
        "did you mean nap?\n"
    )


SPOKEN = """\
name: announce
description: Says the battery level and plays a song.
outcomes: [done]
states:
  SAY:
    speak: {text: "My battery is at {robot.batterylevel} and my volume at {robot.volumne}."}
    transitions: {done: PLAY}
  PLAY:
    play_media: {title: Boleros, file: media/music/bolero.mp3, kind: music}
    transitions: {done: LIGHT}
  LIGHT:
    speak: {text: "It is {env.noise_db} dB here, and {env.colour|grey} outside."}
    transitions: {done: done}
"""


def test_behavior_check_refuses_an_unknown_robot_parameter_and_a_misspelt_medium(
    tmp_path: Path,
) -> None:
    path = tmp_path / "announce.yaml"
    path.write_text(SPOKEN, encoding="utf-8")
    checked = dms("behavior", "check", str(path))
    assert checked.returncode == 1
    assert checked.stdout.splitlines() == [
        f"{path}:6: state SAY: speak: parameter 'text': {{robot.volumne}} binds to nothing: "
        "robot has no parameter 'volumne'; did you mean {robot.voicevolume}?",
        f"{path}:9: state PLAY: play_media: parameter 'file': no medium "
        "'media/music/bolero.mp3' is listed; did you mean 'media/music/boleros.mp3'?",
    ], checked.stdout
    fixed = SPOKEN.replace("robot.volumne", "robot.voicevolume").replace(
        "bolero.mp3", "boleros.mp3"
    )
    path.write_text(fixed, encoding="utf-8")
    assert dms("behavior", "check", str(path)).returncode == 0
    # a parameter the daemon does not document needs a default: a robot may not send it
    path.write_text(fixed.replace("{env.noise_db}", "{env.humidity}"), encoding="utf-8")
    bare = dms("behavior", "check", str(path))
    assert bare.returncode == 1
    assert "{env.humidity} binds to nothing: env has no parameter 'humidity' (one of time," in (
        bare.stdout
    )


def test_a_request_to_pause_one_that_may_not_be_paused_is_logged_as_its_stop(
    tmp_path: Path,
) -> None:
    decisions = _unpausable(tmp_path, "  - {at: 4, request: {action: pause, by: ann}}")
    stops = [d for d in decisions if d["activity"] == "greet_and_ask" and d["action"] != "start"]
    assert [(d["action"], d["reason"], d["detail"]) for d in stops][:1] == [
        ("cancel", "user_request", "requested by ann; it cannot be paused: stopped")
    ], decisions
    assert not [d for d in decisions if d["action"] in ("pause", "resume")], decisions


def test_a_shoulder_touch_on_one_that_may_not_be_paused_stops_it_without_asking(
    tmp_path: Path,
) -> None:
    decisions = _unpausable(tmp_path, "  - {at: 4, touch: right_shoulder}")
    cancel = next(
        d for d in decisions if d["activity"] == "greet_and_ask" and d["action"] == "cancel"
    )
    after = [d for d in decisions if d["time"] >= cancel["time"]]
    stop = after[0]
    assert (stop["action"], stop["reason"]) == ("cancel", "confirm_cancel"), decisions
    assert stop["detail"] == "right shoulder touched; it cannot be paused: stopped", stop
    # nothing is left to continue: "continue or stop?" is not asked
    assert not [d for d in after if d["action"] == "ask"], after
