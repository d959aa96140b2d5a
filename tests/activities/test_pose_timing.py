"""A pose's keyframes with their timing, played on the simulated Mini as the studio does."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from activities import BehaviorError, BehaviorLibrary
from activities.stepper import BehaviorRun
from sim.robot import SimRobot

POSE = """
    name: moves
    outcomes: [done]
    states:
      MOVE:
        pose:
          keyframes: [{neck: 0.5, left_arm: 1.2}, {neck: -0.2}]
          seconds: [3.0, null]
        transitions: {done: done}
    """


def _run(tmp_path: Path, text: str) -> BehaviorRun:
    (tmp_path / "moves.yaml").write_text(textwrap.dedent(text).lstrip())
    library = BehaviorLibrary.load(tmp_path)
    return BehaviorRun(library, library.spec("moves"), SimRobot(rng_seed=0))


def test_each_keyframe_takes_its_seconds_and_the_robot_ends_in_the_last(tmp_path: Path) -> None:
    run = _run(tmp_path, POSE)
    run.run(lambda _step: None)
    sent = [c.args for c in run.commands if c.channel == "motion"]
    assert sent == [
        {"joints": {"neck": 0.5, "left_arm": 1.2}, "duration_s": 3.0},
        {"joints": {"neck": -0.2}},
    ]
    # the first move is held to its 3 s, the second (null) as fast as the neck turns (0.7 rad)
    assert run.t >= 3.0 + 0.7 / 1.6
    joints = run.robot.joints(run.clock.now())  # type: ignore[attr-defined]
    assert joints["neck"] == pytest.approx(-0.2) and joints["left_arm"] == pytest.approx(1.2)


def test_more_times_than_keyframes_is_refused(tmp_path: Path) -> None:
    with pytest.raises(BehaviorError, match="seconds: 2 times for 1 keyframes"):
        _run(tmp_path, POSE.replace("[{neck: 0.5, left_arm: 1.2}, {neck: -0.2}]", "[{neck: 1}]"))
