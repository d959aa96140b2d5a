"""Benchmark: frames and gaze.

- ``lookup_us``: ``FrameStore.lookup`` of a face in a store of 51 frames (the base, the
  body's five, 44 objects half of them two levels deep, the face), relative to the
  head: p50 and p99 over 20,000 lookups (target <= 10 µs with 50 frames);
- ``gaze_update_us``: one ``Attention.update`` per tick while the face moves a little
  each tick (lookup, aim, dead band, rate limit), p50 and p99 over 20,000 ticks
  (target <= 50 µs);
- ``attend_tick_us``: what an attending activity adds to a daemon's tick, all of it: the
  scene taking a fresh ``perception/user`` face and the simulated Mini's joints, the
  ``attend`` gaze keeper, and the aim commands it sends through the expression arbiter
  to the simulated Mini, the face swaying as in ``gaze_update_us`` (target <= 50 µs).

Prints one JSON object.

    .venv/bin/python bench/bench_frames.py [--quick]
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import time
from datetime import UTC, datetime, timedelta

from activities.context import ActivityContext
from activities.gaze import GazeKeeper
from dms.kernel import keys
from dms.kernel.body import HEAD, body_frames
from dms.kernel.expression import ExpressionArbiter
from dms.kernel.frames import FrameStore, pose
from dms.kernel.gaze import EYE_HEIGHT_M, Attention, AttentionSettings
from dms.kernel.messages import UserPerception
from dms.scene import Scene
from sim.robot import SimRobot

T0 = datetime(2026, 11, 24, 10, 0, tzinfo=UTC)
N = 20_000


def _store() -> FrameStore:
    frames = FrameStore(body_frames({"neck": 0.3, "head": 0.1}))
    for index in range(22):
        frames.set(f"object:tray{index}", pose((0.5, 0.1 * index, 0.0)), stamp=T0)
        frames.set(f"object:cup{index}", pose((0.05, 0.0, 0.02)), parent=f"object:tray{index}")
    frames.set("face:ann", pose((0.9, 0.3, EYE_HEIGHT_M)), stamp=T0, stale_after_s=1.0)
    assert len(frames.names) == 51, len(frames.names)
    return frames


def _percentiles(samples: list[float]) -> dict[str, float]:
    cuts = statistics.quantiles(samples, n=100)
    return {"p50": round(cuts[49], 2), "p99": round(cuts[98], 2)}


def bench_lookup(n: int = N) -> dict[str, float]:
    frames = _store()
    now = T0 + timedelta(seconds=0.2)
    samples = []
    for _ in range(n):
        start = time.perf_counter_ns()
        frames.lookup("face:ann", now, reference=HEAD)
        samples.append((time.perf_counter_ns() - start) / 1000)
    return _percentiles(samples)


def bench_gaze(n: int = N) -> dict[str, float]:
    frames = _store()
    attention = Attention("face:ann")
    samples = []
    for tick in range(n):
        now = T0 + timedelta(seconds=tick * 0.5)
        sway = 0.3 + 0.2 * math.sin(tick / 10)
        frames.set("face:ann", pose((0.9, sway, EYE_HEIGHT_M)), stamp=now, stale_after_s=1.0)
        start = time.perf_counter_ns()
        attention.update(frames, now)
        samples.append((time.perf_counter_ns() - start) / 1000)
    return {**_percentiles(samples), "shifts": attention.shifts}


def bench_attend_tick(n: int = N) -> dict[str, float]:
    robot = SimRobot()
    scene = Scene(joints=robot.joints)
    arbiter = ExpressionArbiter(robot, lambda _command: None)
    ctx = ActivityContext(arbiter, "activity:quiz", frames=scene.frames, joints=scene.joints)
    keeper = GazeKeeper(ctx, "user", AttentionSettings())
    fresh = frozenset({keys.PERCEPTION_USER})
    samples = []
    for tick in range(n):
        now = T0 + timedelta(seconds=tick * 0.5)
        sway = round(0.3 + 0.2 * math.sin(tick / 10), 2)  # a tracker's centimetres
        user = UserPerception.model_validate(
            {
                "present": True,
                "user_id": "ann",
                "ready": True,
                "face": {"position": {"x": 0.9, "y": sway, "z": EYE_HEIGHT_M}},
            }
        )
        values = {keys.PERCEPTION_USER: user}
        start = time.perf_counter_ns()
        scene.update(values, fresh, now)
        arbiter.update(now)
        keeper.update(now)
        samples.append((time.perf_counter_ns() - start) / 1000)
    return {**_percentiles(samples), "aims": arbiter.sent}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="1,000 samples each (smoke)")
    quick = parser.parse_args().quick
    n = 1000 if quick else N
    print(
        json.dumps(
            {
                "frames": 51,
                "samples": n,
                "lookup_us": bench_lookup(n),
                "gaze_update_us": bench_gaze(n),
                "attend_tick_us": bench_attend_tick(n),
                "targets_us": {"lookup": 10, "gaze_update": 50, "attend_tick": 50},
            }
        )
    )


if __name__ == "__main__":
    main()
