"""A real session's Table 4, measured by a real daemon and read back by ``dms sessions``.

Ann arrives, a caregiver's app starts and cancels activities, Ann asks for one herself
and leaves; Bob arrives and is still there when the daemon stops. Both sessions are
stored with their metrics (Ann's when she leaves, Bob's at shutdown), and the counts
read back agree with the decisions seen on ``dms/decision``.
"""

from __future__ import annotations

import csv
import io
import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from dms.kernel.session_metrics import METRIC_KEYS
from tests.integration.harness import Collector, put, running_daemon

pytestmark = pytest.mark.integration

NOT_COUNTED = {"menu", "notification", "wait", "sleep", "instructions"}


def _sessions(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "dms.cli", "sessions", *args],
        capture_output=True,
        text=True,
        timeout=60,
    )


def _counts(decisions: list[dict[str, Any]]) -> dict[str, int]:
    """Robot decisions, user selections and cancels as Table 4 counts them."""
    counted = [d for d in decisions if d["activity"] not in NOT_COUNTED]
    starts = [d for d in counted if d["action"] == "start"]
    return {
        "robot_decisions_per_session": sum(d["chosen_by"] == "robot" for d in starts),
        "user_selections_per_session": sum(d["chosen_by"] == "user" for d in starts),
        "cancels_per_session": sum(
            d["action"] == "cancel" and d["reason"] in ("confirm_cancel", "user_request")
            for d in counted
        ),
    }


def test_a_real_session_is_stored_with_its_metrics_and_read_back(tmp_path: Path) -> None:
    with running_daemon(tmp_path) as (daemon, session):
        decisions = Collector(session, "robots/mini/dms/decision")
        states = Collector(session, "robots/mini/dms/state")
        states.wait_count(1)
        ann_from = decisions.mark()  # nothing is counted before her session: no user
        put(session, "perception/user", {"present": True, "user_id": "ann", "ready": True})
        states.wait_for(lambda s: (s["user"] or {}).get("id") == "ann")
        for activity in ("jokes", "cognitive_stimulation"):  # not a pick of the robot
            mark = decisions.mark()
            put(session, "request", {"action": "start", "activity": activity, "by": "app"})
            decisions.wait_for(
                lambda d, a=activity: d["action"] == "start" and d["activity"] == a, start=mark
            )
            mark = decisions.mark()
            put(session, "request", {"action": "cancel", "activity": activity, "by": "app"})
            decisions.wait_for(
                lambda d, a=activity: d["action"] == "cancel" and d["activity"] == a, start=mark
            )
        mark = decisions.mark()
        put(session, "request", {"action": "start", "activity": "quiz", "by": "ann"})
        decisions.wait_for(lambda d: d["action"] == "start" and d["activity"] == "quiz", start=mark)
        running = states.mark()  # the quiz runs a few ticks: its first command is heard
        states.wait_count(running + 3)
        put(session, "perception/user", {"present": False, "user_id": None, "ready": False})
        left = states.wait_for(lambda s: s["user"] is None, start=states.mark())
        ann_decisions = [d for d in decisions.messages[ann_from:] if d["time"] <= left["time"]]
        bob_since = left["time"]
        put(session, "perception/user", {"present": True, "user_id": "bob", "ready": True})
        states.wait_for(lambda s: (s["user"] or {}).get("id") == "bob", start=states.mark())
        assert daemon.terminate() == 0  # Bob's session ends at shutdown

    exported = _sessions("export", "--format", "json", "--db", daemon.db)
    assert exported.returncode == 0, exported.stderr
    rows = json.loads(exported.stdout)
    assert [r["user"] for r in rows] == ["ann", "bob"]
    ann, bob = rows
    assert ann["ended"] is not None and bob["ended"] is not None
    assert {k: ann[k] for k in _counts(ann_decisions)} == _counts(ann_decisions)
    # The app's two cancels at least (a start also cancels what runs, a user_request).
    assert ann["cancels_per_session"] >= 2 and ann["user_selections_per_session"] >= 3
    assert ann["activities_per_session"] >= 3
    assert ann["activity_time_s"] is not None and ann["activity_time_s"] > 0
    assert ann["change_time_s"] is not None and ann["change_time_s"] >= 0
    # The simulated Mini reports a start for every command: each activity loaded.
    assert ann["activity_load_time_s"] is not None and 0 <= ann["activity_load_time_s"] < 5
    assert bob["duration_s"] is not None and bob["duration_s"] >= 0

    as_csv = _sessions("export", "--format", "csv", "--db", daemon.db)
    assert as_csv.returncode == 0, as_csv.stderr
    table = list(csv.DictReader(io.StringIO(as_csv.stdout)))
    assert list(table[0]) == list(rows[0]) == ["session", "user", "started", "ended", *METRIC_KEYS]
    for row, parsed in zip(table, rows, strict=True):
        assert row == {k: "" if v is None else str(v) for k, v in parsed.items()}

    later = _sessions("export", "--since", bob_since, "--db", daemon.db)
    assert [r["user"] for r in json.loads(later.stdout)] == ["bob"]
    future = _sessions("export", "--since", "2999-01-01", "--db", daemon.db)
    assert json.loads(future.stdout) == []

    listed = _sessions("list", "--db", daemon.db)
    assert listed.returncode == 0, listed.stderr
    assert "ann" in listed.stdout and "bob" in listed.stdout and "mean" in listed.stdout


def test_a_database_that_does_not_exist_is_refused_and_not_created(tmp_path: Path) -> None:
    missing = tmp_path / "nowhere.db"
    for command in ("list", "export"):
        result = _sessions(command, "--db", str(missing))
        assert result.returncode == 1
        assert result.stderr.strip().count("\n") == 0
        assert f"no database at {missing}" in result.stderr
        assert not missing.exists()
