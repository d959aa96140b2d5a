"""``dms record --out FILE.mcap`` as a real process beside a real daemon, on 127.0.0.1.

Every wait is for a message (or Zenoh's matching status), with a deadline.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
import zenoh
from mcap.reader import make_reader

from sim.recording import read_recording
from tests.integration.harness import Collector, put, running_daemon, wait_subscribed

pytestmark = pytest.mark.integration

PROBE = "robots/mini/test/probe"
"""A key only the recorder (``robots/mini/**``) subscribes to."""


def _record(out: Path, port: int) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [
            sys.executable,
            "-m",
            "dms.cli",
            "record",
            "--out",
            str(out),
            "--connect",
            f"tcp/127.0.0.1:{port}",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=dict(os.environ, PYTHONUNBUFFERED="1"),
    )


def _record_one_visit(
    session: zenoh.Session,
    port: int,
    out: Path,
    stop_signal: signal.Signals,
    decisions: Collector,
    states: Collector,
) -> tuple[list[dict[str, Any]], str]:
    """Record a visit (arrive, ask for jokes, leave); stop; the decisions seen and stderr."""
    first = decisions.mark()
    recorder = _record(out, port)
    try:
        wait_subscribed(session, PROBE)
        put(session, "perception/user", {"present": True, "user_id": "alice", "ready": True})
        decisions.wait_for(lambda d: d["reason"] == "user_arrived", start=first)
        put(session, "request", {"action": "start", "activity": "jokes", "by": "test"})
        decisions.wait_for(lambda d: d["activity"] == "jokes", start=first)
        put(session, "perception/user", {"present": False, "user_id": None, "ready": False})
        left = decisions.wait_for(lambda d: d["reason"] == "user_left", start=first)
        # The daemon publishes to the recorder and to us at once; two ticks later the
        # recorder has had the decisions of the user_left tick.
        states.wait_for(lambda s: s["tick"] >= left["tick"] + 2)
        seen = decisions.messages[first:]
        recorder.send_signal(stop_signal)
        _, err = recorder.communicate(timeout=20.0)
    finally:
        if recorder.poll() is None:
            recorder.kill()
            recorder.wait(10)
    assert recorder.returncode == 0, err
    return seen, err


def test_record_command_writes_the_decisions_with_their_schemas(tmp_path: Path) -> None:
    with running_daemon(tmp_path, "user_initiative = { unknown = 1.0 }\n") as (daemon, session):
        decisions = Collector(session, "robots/mini/dms/decision")
        states = Collector(session, "robots/mini/dms/state")
        visits = []
        for stop_signal in (signal.SIGINT, signal.SIGTERM):
            out = tmp_path / f"{stop_signal.name}.mcap"
            seen, err = _record_one_visit(session, daemon.port, out, stop_signal, decisions, states)
            visits.append((out, seen, err))
    for out, seen, err in visits:
        _check_recording(out, seen, err)


def _check_recording(out: Path, seen: list[dict[str, Any]], err: str) -> None:
    """``out`` is complete, holds every decision in ``seen`` and the schemas of its keys."""
    summary = err.strip().splitlines()[-1]
    assert summary.startswith("dms: ") and " messages recorded (" in summary, err
    assert "dms/decision" in summary

    recording = read_recording(out)
    assert recording.truncated is None
    recorded = [m.payload for m in recording.messages if m.key == "dms/decision"]
    assert [_decision_key(d) for d in seen if d in recorded] == [_decision_key(d) for d in seen]
    assert {"user_arrived", "user_request", "user_left"} <= {d["reason"] for d in recorded}
    keys = {m.key for m in recording.messages}
    assert {"perception/user", "request", "dms/state", "dms/decision", "robot/command"} <= keys

    # Every contract key is on a channel with its JSON Schema (what Foxglove reads).
    with out.open("rb") as stream:
        summary_records = make_reader(stream).get_summary()
    assert summary_records is not None
    schemas = summary_records.schemas
    by_topic = {c.topic: c for c in summary_records.channels.values()}
    decision_channel = by_topic["robots/mini/dms/decision"]
    assert decision_channel.message_encoding == "json"
    schema = schemas[decision_channel.schema_id]
    assert schema.encoding == "jsonschema"
    assert {"tick", "action", "activity", "reason"} <= set(json.loads(schema.data)["properties"])
    user_schema = schemas[by_topic["robots/mini/perception/user"].schema_id]
    assert "present" in json.loads(user_schema.data)["properties"]


def _decision_key(decision: dict[str, Any]) -> tuple[object, ...]:
    return (decision["tick"], decision["action"], decision["activity"], decision["reason"])


def test_record_command_with_an_unwritable_out_is_one_line(tmp_path: Path) -> None:
    out = tmp_path / "missing" / "folder" / "session.mcap"
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "dms.cli",
            "record",
            "--out",
            str(out),
            "--connect",
            "tcp/127.0.0.1:9",
        ],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode != 0
    lines = done.stderr.splitlines()
    assert len(lines) == 1, done.stderr
    assert lines[0].startswith(f"dms: {out}: cannot write: ")
    assert "Traceback" not in done.stderr
    assert not out.exists()
