"""A failing output channel backs off: an activity whose speech keeps failing is not
started again and again (menu, fail, menu, fail), but tried after a wait that doubles,
and ``dms/state`` says which channel fails.

Real controller stack on a virtual clock with the simulated Mini, whose speech channel
is made to fail; the user is scripted.
"""

from __future__ import annotations

import json

from dms.kernel import keys
from dms.kernel.messages import Request
from sim.harness import Simulation
from tests.core.scripted import quiet_settings, seated

MENU_FIRST = {"user_initiative": {"unknown": 1.0}}
"""The user always has the initiative: the robot opens the menu, which speaks."""


def _failing_speech() -> Simulation:
    sim = seated(quiet_settings(MENU_FIRST))
    sim.robot.set_fault("speech", "fail")
    return sim


def _fails(sim: Simulation, start: float, end: float) -> list[float]:
    return [t.t for t in sim.decisions if start <= t.t < end and t.decision.action == "fail"]


def test_a_failing_speech_channel_fails_a_few_times_a_minute_at_most() -> None:
    with _failing_speech() as sim:
        sim.run_for(180)
        assert len(_fails(sim, 0, 60)) <= 4, _fails(sim, 0, 180)
        for minute in (60, 120):
            assert len(_fails(sim, minute, minute + 60)) <= 2, _fails(sim, 0, 180)
        assert _fails(sim, 0, 180), "the channel was tried again, not given up"


def test_dms_state_says_which_channel_fails_and_when_it_works_again() -> None:
    with _failing_speech() as sim:
        sim.run_for(5)
        state = sim.controller.state
        assert state is not None and state.failing_channel == "speech"
        assert json.loads(state.model_dump_json())["failing_channel"] == "speech"
        assert any("speech channel fails" in error for _, _, error in sim.errors)
        sim.robot.set_fault("speech", None)
        sim.run_for(400)  # the next probe, within the longest wait
        state = sim.controller.state
        assert state is not None and state.failing_channel is None
        assert "failing_channel" not in json.loads(state.model_dump_json())
        assert any("speech channel works again" in error for _, _, error in sim.errors)
        assert not _fails(sim, 5, sim.t)


def test_what_the_user_asks_for_is_tried_during_the_back_off() -> None:
    with _failing_speech() as sim:
        sim.run_for(5)
        assert sim.controller.runner.blocked
        sim.feed(keys.REQUEST, Request(action="start", activity="bingo", by="ann"))
        decisions = list(sim.tick(urgent=True).decisions)
        started = [(d.activity, d.reason) for d in decisions if d.action == "start"]
        assert started == [("bingo", "user_request")]


def test_a_state_without_a_failing_channel_is_published_as_before() -> None:
    with seated(quiet_settings(MENU_FIRST)) as sim:
        sim.run_for(5)
        state = sim.controller.state
        assert state is not None and state.failing_channel is None
        assert "failing_channel" not in json.loads(state.model_dump_json())
