"""``dms record`` -> ``dms record info`` -> ``dms sim replay FILE`` with no flags, each the
real command in a subprocess beside a real daemon over Zenoh on 127.0.0.1.

The recorder stores the daemon's seed, settings and files (MCAP metadata and
attachments) in zstd chunks, so the replay needs neither ``--seed`` nor ``--config``.
Every wait is for a message, Zenoh's matching status or a process's exit.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from mcap.reader import make_reader

from activities.library import BEHAVIORS_DIR
from tests.integration.harness import (
    Collector,
    StderrLines,
    free_port,
    put,
    running_daemon,
    wait_subscribed,
)

pytestmark = pytest.mark.integration

_SCRIPT = Path(sys.executable).with_name("dms")
DMS = [str(_SCRIPT)] if _SCRIPT.exists() else [sys.executable, "-m", "dms.cli"]
PROBE = "robots/mini/test/record-probe"


def dms(*args: str, timeout: float = 120) -> subprocess.CompletedProcess[str]:
    clean = {k: v for k, v in os.environ.items() if not k.startswith("DMS_")}
    return subprocess.run([*DMS, *args], capture_output=True, text=True, timeout=timeout, env=clean)


def test_record_info_replay_round_trip_with_no_flags(tmp_path: Path) -> None:
    out = tmp_path / "visit.mcap"
    zenoh_file = tmp_path / "recorder.json5"
    # The user always takes the initiative: no random draw before the recording starts.
    with running_daemon(tmp_path, "user_initiative = { unknown = 1.0 }\n") as (daemon, session):
        zenoh_file.write_text(
            json.dumps(
                {
                    "mode": "peer",
                    "connect": {"endpoints": [f"tcp/127.0.0.1:{daemon.port}"]},
                    "scouting": {"multicast": {"enabled": False}},
                }
            )
        )
        decisions = Collector(session, "robots/mini/dms/decision")
        states = Collector(session, "robots/mini/dms/state")
        recorder = subprocess.Popen(
            [*DMS, "record", "--out", str(out), "--zenoh-config", str(zenoh_file)],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
            env=dict(os.environ, PYTHONUNBUFFERED="1"),
        )
        lines = StderrLines(recorder)
        try:
            wait_subscribed(session, PROBE)
            # The daemon answered the recorder's dms/config: their link is up.
            lines.wait_for("configuration for replay")
            # Two ticks on, the recorder holds a state from before the visit.
            now = states.wait_for(lambda s: True, start=states.mark())
            states.wait_for(lambda s: s["tick"] >= now["tick"] + 2)
            first = decisions.mark()
            put(session, "perception/user", {"present": True, "user_id": "alice", "ready": True})
            decisions.wait_for(lambda d: d["reason"] == "user_arrived", start=first)
            put(session, "request", {"action": "start", "activity": "jokes", "by": "test"})
            decisions.wait_for(lambda d: d["activity"] == "jokes", start=first)
            put(session, "perception/user", {"present": False, "user_id": None, "ready": False})
            left = decisions.wait_for(lambda d: d["reason"] == "user_left", start=first)
            # Two ticks on, the recorder has had every decision of the user_left tick.
            states.wait_for(lambda s: s["tick"] >= left["tick"] + 2)
            recorder.send_signal(signal.SIGINT)
            recorder.wait(30.0)
            err = lines.text()
        finally:
            if recorder.poll() is None:
                recorder.kill()
                recorder.wait(10)
        assert recorder.returncode == 0, err
        assert daemon.terminate() == 0
    summary = err.strip().splitlines()[-1]
    assert " messages recorded (" in summary and "not stored" not in summary, err

    # The file: zstd chunks, the configuration as metadata, the files as attachments.
    with out.open("rb") as stream:
        reader = make_reader(stream)
        found = reader.get_summary()
        assert found is not None
        assert {chunk.compression for chunk in found.chunk_indexes} == {"zstd"}
        metadata = {m.name: m.metadata for m in reader.iter_metadata()}
        attachments = {a.name: a.data for a in reader.iter_attachments()}
    assert json.loads(metadata["dms-config"]["seed"]) == 3
    assert attachments["behaviors/jokes.yaml"] == (BEHAVIORS_DIR / "jokes.yaml").read_bytes()
    assert "content/jokes.yaml" in attachments
    settings = json.loads(metadata["dms-config"]["settings"])
    assert settings["controller"]["user_initiative"]["unknown"] == 1.0
    assert "db" not in settings  # a database URL may hold a password

    # record info, as text and as JSON.
    info = dms("record", "info", str(out))
    assert info.returncode == 0, info.stderr
    for text in ("Duration:", "zstd", "Seed:          3", "robots/mini/dms/decision", "Decision"):
        assert text in info.stdout, (text, info.stdout)
    described = json.loads(dms("record", "info", str(out), "--json").stdout)
    assert described["config"]["seed"] == 3 and described["complete"] is True
    counts = {t["topic"]: t["count"] for t in described["topics"]}
    assert counts["robots/mini/dms/decision"] >= 3
    assert described["compressed_bytes"] < described["uncompressed_bytes"]

    # The replay, with no flags: the recorded seed and settings, the same decisions.
    replayed = dms("sim", "replay", str(out))
    assert replayed.returncode == 0, replayed.stdout + replayed.stderr
    assert "the recorded seed 3" in replayed.stdout
    assert "the replayed decisions are the recorded ones" in replayed.stdout
    report = json.loads(dms("sim", "replay", str(out), "--json").stdout)
    assert report["same"] and report["recorded_decisions"] >= 3


def test_record_against_nothing_exits_1_and_keeps_no_file(tmp_path: Path) -> None:
    out = tmp_path / "empty.mcap"
    port = free_port()  # nobody listens there
    result = dms(
        "record", "--out", str(out), "--connect", f"tcp/127.0.0.1:{port}", "--duration", "1"
    )
    assert result.returncode == 1, result.stderr
    last = result.stderr.strip().splitlines()[-1]
    assert last.startswith("dms: recorded nothing from robots/mini/** in "), result.stderr
    assert f"tcp/127.0.0.1:{port}" in last and "Traceback" not in result.stderr
    assert not out.exists()


def test_record_refusals_are_one_line(tmp_path: Path) -> None:
    bad = tmp_path / "bad.json5"
    bad.write_text("{mode: ")
    result = dms("record", "--out", str(tmp_path / "x.mcap"), "--zenoh-config", str(bad))
    assert result.returncode == 1
    assert result.stderr.strip().startswith(f"dms: --zenoh-config {bad}: ")
    assert len(result.stderr.strip().splitlines()) == 1
    missing = dms("record", "info", str(tmp_path / "absent.mcap"))
    assert missing.returncode == 1 and missing.stderr.startswith("dms: ")
    assert len(missing.stderr.strip().splitlines()) == 1
    bad_key = dms("record", "--key", "dms/a?b", "--duration", "1")
    assert bad_key.returncode == 1 and bad_key.stderr.startswith("dms: "), bad_key.stderr
