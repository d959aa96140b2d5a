"""Any sequence of commands and events leaves an activity consistent (Hypothesis)."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from activities import ActivityStatus, BehaviorLibrary
from dms.kernel.messages import ScreenChoice, Speech, Touch
from tests.activities.conftest import Bench

LIBRARY = BehaviorLibrary.load()
OPS = st.sampled_from(
    ["tick", "tick", "tick", "wait", "pause", "resume", "answer", "screen", "touch", "other"]
)


@settings(max_examples=60, deadline=None)
@given(
    name=st.sampled_from(["quiz", "bingo", "dance", "talk", "cognitive_stimulation", "menu"]),
    ops=st.lists(OPS, max_size=60),
)
def test_random_commands_keep_the_activity_consistent(name: str, ops: list[str]) -> None:
    bench = Bench(LIBRARY)
    activity = bench.start(bench.create(name))
    source = f"activity:{name}"
    for op in ops:
        if op == "tick":
            bench.advance(activity, 0.5)
        elif op == "wait":
            bench.advance(activity, 20, step=1.0)
        elif op == "pause":
            activity.pause(bench.now)
            assert bench.expression.pending(source) == []
        elif op == "resume":
            activity.resume(bench.now)
        elif op == "answer":
            activity.deliver(Speech(text="Paris", confidence=0.9))
        elif op == "screen":
            activity.deliver(ScreenChoice(choice="quiz"))
        elif op == "touch":
            activity.deliver(Touch(part="left_shoulder", kind="tap"))
        else:
            assert not activity.deliver(Speech(text="let's dance", confidence=0.9)) or name in (
                "menu",
                "talk",
            )
        speaking = [h for h in bench.expression.pending() if h.channel == "speech"]
        assert sum(h.status.value in ("sent", "started") for h in speaking) <= 1
        assert activity.status in set(ActivityStatus)
        if activity.status is ActivityStatus.PAUSED:
            assert bench.expression.pending(source) == []
    activity.cancel(bench.now)
    assert activity.finished
    assert bench.expression.pending(source) == []
