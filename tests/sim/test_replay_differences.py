"""``dms sim replay`` when the replayed decisions differ from the recorded ones.

The recording is written with :class:`sim.recording.McapRecorder`: a user arrives and
asks for jokes, and a ``dms/state`` every 0.5 s gives the recorded ticks. Its decisions
are first those the controller takes on it (so the file replays identically), then one
of them is altered, as a daemon with other rules or settings would have decided.
"""

from __future__ import annotations

import json
from datetime import UTC, datetime, timedelta
from pathlib import Path

import pytest

from dms.cli import main
from dms.config import Settings, load_config
from dms.kernel.clock import iso
from dms.kernel.messages import Decision
from sim.recording import McapRecorder
from sim.replay import replay

START = datetime(2026, 11, 23, 10, 0, tzinfo=UTC)
SPAN_S = 20.0
CONFIG = (
    "seed = 3\n[controller]\nsession_questions = 0\nquestion_every = 0\n"
    "feedback_probability = 0.0\nuser_initiative = { unknown = 1.0 }\n"
)


def _ns(t: float) -> int:
    return int((START + timedelta(seconds=t)).timestamp() * 1e9)


def _write(path: Path, decisions: list[Decision]) -> None:
    """A recording of the scripted inputs, the 2 Hz states and ``decisions``."""
    recorder = McapRecorder(path, "mini")
    user = {"present": True, "user_id": "alice", "ready": True, "engagement": None}
    request = {"action": "start", "activity": "jokes", "by": "test"}
    messages: list[tuple[int, str, object]] = [
        (_ns(0.1), "perception/user", user),
        (_ns(2.0), "request", request),
    ]
    for tick in range(int(SPAN_S * 2) + 1):
        at = START + timedelta(seconds=tick * 0.5)
        messages.append((_ns(tick * 0.5) + 1, "dms/state", {"tick": tick, "time": iso(at)}))
    for decision in decisions:
        when = datetime.fromisoformat(decision.time.replace("Z", "+00:00"))
        messages.append(
            (int(when.timestamp() * 1e9) + 2, "dms/decision", decision.model_dump(mode="json"))
        )
    for log_ns, key, payload in sorted(messages, key=lambda m: m[0]):
        assert recorder.write(f"robots/mini/{key}", json.dumps(payload).encode(), log_ns)
    recorder.close()


@pytest.fixture
def settings(tmp_path: Path) -> tuple[Path, Settings]:
    config = tmp_path / "dms.toml"
    config.write_text(CONFIG)
    return config, load_config(config).model_copy(update={"db": None})


@pytest.fixture
def decided(tmp_path: Path, settings: tuple[Path, Settings]) -> list[Decision]:
    """The decisions the controller takes on the scripted inputs."""
    bare = tmp_path / "inputs.mcap"
    _write(bare, [])
    report = replay(bare, seed=3, settings=settings[1])
    keys = [(d.action, d.activity, d.reason) for d in report.replayed]
    assert ("start", "jokes", "user_request") in keys, keys
    return report.replayed


def test_identical_recording_replays_with_exit_0(
    tmp_path: Path,
    settings: tuple[Path, Settings],
    decided: list[Decision],
    capsys: pytest.CaptureFixture[str],
) -> None:
    path = tmp_path / "same.mcap"
    _write(path, decided)
    assert main(["sim", "replay", str(path), "--config", str(settings[0])]) == 0
    captured = capsys.readouterr()
    assert "the replayed decisions are the recorded ones" in captured.out
    assert captured.err == ""


def test_a_changed_decision_is_reported_with_its_time_and_both_sides(
    tmp_path: Path,
    settings: tuple[Path, Settings],
    decided: list[Decision],
    capsys: pytest.CaptureFixture[str],
) -> None:
    index = next(i for i, d in enumerate(decided) if d.activity == "jokes" and d.action == "start")
    original = decided[index]
    # The recorded daemon started the quiz, chosen by the robot, where the replay starts jokes.
    altered = original.model_copy(
        update={"activity": "quiz", "reason": "preference", "chosen_by": "robot"}
    )
    path = tmp_path / "differs.mcap"
    _write(path, [*decided[:index], altered, *decided[index + 1 :]])

    report = replay(path, seed=3, settings=settings[1])
    assert not report.same
    assert len(report.differences) == 1
    difference = report.differences[0]
    assert difference.time == original.time
    clock = original.time[11:23]
    assert difference.recorded == [f"{clock} start quiz [preference by robot]"]
    assert difference.replayed == [f"{clock} start jokes [user_request by user]"]
    as_json = report.to_json()
    assert as_json["same"] is False
    assert as_json["differences"] == [
        {"time": original.time, "recorded": difference.recorded, "replayed": difference.replayed}
    ]

    assert main(["sim", "replay", str(path), "--config", str(settings[0])]) == 1
    captured = capsys.readouterr()
    assert f"  {original.time}: recorded {clock} start quiz" in captured.out
    assert "replayed " + clock + " start jokes [user_request by user]" in captured.out
    lines = captured.err.splitlines()
    assert lines == [
        f"dms: {path}: 1 difference(s) from the recorded decisions, the first at {original.time}"
    ]


def test_a_missing_decision_is_reported_as_nothing_recorded(
    tmp_path: Path, settings: tuple[Path, Settings], decided: list[Decision]
) -> None:
    last = decided[-1]
    path = tmp_path / "shorter.mcap"
    _write(path, decided[:-1])
    report = replay(path, seed=3, settings=settings[1])
    assert [(d.time, d.recorded) for d in report.differences] == [(last.time, [])]
    assert len(report.differences[0].replayed) == 1
    assert "recorded nothing | replayed" in report.text()


def test_an_urgent_input_is_fed_at_its_own_tick_whichever_process_lagged() -> None:
    """The recorder may log a request a little before or after the daemon's urgent tick
    on it (tens of milliseconds on a loaded machine); the replay finds that tick off the
    2 Hz grid, not a regular tick nearby."""
    from datetime import UTC, datetime, timedelta

    from sim.replay import _feed_time, _off_grid

    t0 = datetime(2026, 11, 27, 21, 39, 50, 386000, tzinfo=UTC)
    regular = [t0 + timedelta(seconds=0.5 * k) for k in range(8)]
    urgent_tick = t0 + timedelta(seconds=2.539)  # a request, 39 ms after a regular tick
    ticks = sorted([*regular, urgent_tick])
    urgent = _off_grid(ticks, 0.5)
    assert urgent == {urgent_tick}
    late = urgent_tick + timedelta(milliseconds=60)  # the recorder lagged
    assert _feed_time("request", late, ticks, urgent) == urgent_tick
    early = urgent_tick - timedelta(milliseconds=30)  # the daemon lagged: fed just before
    assert _feed_time("request", early, ticks, urgent) == early
    assert _feed_time("perception/user", late, ticks, urgent) == late  # not urgent
