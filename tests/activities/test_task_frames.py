"""Task frames: places relative to a detected marker, kept where last known once it is lost.

As ROS Commander defines a task frame relative to an AR tag: the behavior declares
``frames: {handle: {of: object:tag, xyz: [...]}}`` and aims at ``handle``. The frames
are a real :class:`FrameStore`, the robot the simulated Mini (see test_gaze_blocks).
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from activities import BehaviorError, BehaviorLibrary
from dms.kernel.frames import pose
from tests.activities.conftest import write_behaviors
from tests.activities.test_gaze_blocks import GazeBench

LOOK_TWICE = """
    name: handle
    outcomes: [done, lost]
    frames:
      handle: {of: "object:tag", xyz: [0.1, 0.0, 0.2]}
    states:
      FIRST:
        look_at: {frame: handle}
        transitions: {done: HOLD}
      HOLD:
        wait: {seconds: 3}
        transitions: {done: AGAIN}
      AGAIN:
        point_at: {frame: handle}
"""


def _bench(tmp_path: Path, text: str) -> GazeBench:
    return GazeBench(BehaviorLibrary.load(write_behaviors(tmp_path, {"handle": text})))


def test_a_task_frame_follows_its_marker_then_stays_where_it_was_last_known(
    tmp_path: Path,
) -> None:
    bench = _bench(tmp_path, LOOK_TWICE)
    # the tag lies turned a quarter to the left: its x axis is the robot's y axis
    tag = pose((0.5, 0.2, 0.1), rpy=(0.0, 0.0, math.pi / 2))
    bench.frames.set("object:tag", tag, stamp=bench.now, stale_after_s=1.0)
    activity = bench.start(bench.create("handle"))
    while len(bench.aims()) < 1:
        bench.step(activity, 0.1)
    first = bench.aims()[0]
    assert first["frame"] == "handle" and first["live"] is True
    assert first["position"] == pytest.approx({"x": 0.5, "y": 0.3, "z": 0.3}, abs=1e-4)
    bench.frames.forget("object:tag")  # the tag is taken away: the scene forgets it
    bench.finish(activity, limit_s=10)
    assert activity.result.outcome == "done"
    again = bench.aims()[1]
    assert again["live"] is False and again["position"] == first["position"]
    assert bench.joints()["left_arm"] > 1.0  # the arm points where the handle was


def test_a_task_frame_whose_marker_was_never_seen_is_lost(tmp_path: Path) -> None:
    bench = _bench(tmp_path, LOOK_TWICE)
    activity = bench.start(bench.create("handle"))
    bench.finish(activity, limit_s=10)
    assert activity.result.outcome == "lost" and bench.aims() == []


@pytest.mark.parametrize(
    ("old", "new", "problem"),
    [
        ("{frame: handle}", "{frame: handel}", "no task frame 'handel'; did you mean 'handle'?"),
        ('handle: {of: "object:tag"', 'user: {of: "object:tag"', "frames: user: the robot has"),
        (
            '{of: "object:tag"',
            '{of: "tag"',
            "of: frame 'tag' cannot exist; did you mean 'object:tag'",
        ),
        ("xyz: [0.1, 0.0, 0.2]", "xyz: [0.1, 0.2]", "frames: handle: xyz: three numbers (metres"),
        ("xyz: [0.1, 0.0, 0.2]", "xyz: [0.1, 0.0, 0.2], size: 3", "unknown key 'size'"),
    ],
)
def test_a_task_frame_written_wrong_is_refused_at_its_line(
    tmp_path: Path, old: str, new: str, problem: str
) -> None:
    assert old in LOOK_TWICE
    with pytest.raises(BehaviorError) as refused:
        _bench(tmp_path, LOOK_TWICE.replace(old, new, 1))
    assert any(problem in line for line in refused.value.problems), refused.value.problems
