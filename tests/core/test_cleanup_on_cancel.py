"""At the controller, a cancel preempts the activity the SMACH way.

Real controller stack on a virtual clock (real SQLite, the simulated Mini). The cancel
decision and the next start come in the same tick; the cancelled activity's cleanup
states run on (the quiz says it stops, with the score) and the next activity's speech
follows them; shutdown and ``cleanup_limit_s = 0`` still stop at once.
"""

from __future__ import annotations

from datetime import datetime

from dms.kernel import keys
from dms.kernel.messages import Request, RobotCommand, Speech, Touch
from sim.harness import Simulation
from tests.core.scripted import quiet_settings, seated


def _sim(**controller: object) -> Simulation:
    return seated(quiet_settings(dict(controller)))


def _speech(sim: Simulation) -> list[str]:
    said: list[str] = []

    def on(command: RobotCommand, _now: datetime) -> None:
        if command.channel == "speech":
            said.append(str(command.args.get("text", "")))

    sim.command_listeners.append(on)
    return said


def _request(sim: Simulation, activity: str) -> list[tuple[str, str | None]]:
    sim.feed(keys.REQUEST, Request(action="start", activity=activity, by="caregiver"))
    record = sim.tick(urgent=True)
    return [(d.action, d.activity) for d in record.decisions]


def _path(sim: Simulation) -> str:
    state = sim.controller.build_state(sim.now()).activity
    return state.state if state is not None else ""


def _quiz_mid_question(sim: Simulation) -> None:
    _request(sim, "quiz")
    end = sim.t + 120
    while "ASK" not in _path(sim) and sim.t < end:
        sim.run_for(0.5)
    assert "ASK" in _path(sim), "the quiz never asked"


def test_a_cancelled_quiz_says_it_stops_before_the_next_activity_speaks() -> None:
    with _sim() as sim:
        said = _speech(sim)
        _quiz_mid_question(sim)
        decisions = _request(sim, "bingo")
        assert decisions == [("cancel", "quiz"), ("start", "bingo")], "one tick, as asked"
        winding = [a.name for m in sim.controller.managers.values() for a in m.winding_down]
        assert winding == ["quiz"]
        sim.run_for(30)
        stop = next(i for i, t in enumerate(said) if "stop the quiz here" in t)
        bingo = next(i for i, t in enumerate(said) if t.startswith("Let's play bingo"))
        assert stop < bingo
        assert all(not m.winding_down for m in sim.controller.managers.values())


def test_no_cleanup_when_the_limit_is_zero() -> None:
    with _sim(cleanup_limit_s=0) as sim:
        said = _speech(sim)
        _quiz_mid_question(sim)
        _request(sim, "bingo")
        sim.run_for(30)
        assert not any("stop the quiz" in t for t in said)
        assert any(t.startswith("Let's play bingo") for t in said)


def test_shutdown_stops_at_once_without_cleanup() -> None:
    with _sim() as sim:
        said = _speech(sim)
        _quiz_mid_question(sim)
        _request(sim, "bingo")  # the quiz is cleaning up, bingo runs
        record = sim.controller.shutdown(sim.now())
        assert [(d.action, d.activity) for d in record.decisions] == [("cancel", "bingo")]
        assert all(not m.winding_down for m in sim.controller.managers.values())
        count = len(said)
        sim.stack.expression.update(sim.now())
        assert len(said) == count, "nothing more is said after shutdown"


def test_stop_on_the_shoulder_dialog_runs_the_quiz_cleanup() -> None:
    with _sim() as sim:
        said = _speech(sim)
        _quiz_mid_question(sim)
        sim.feed(keys.PERCEPTION_TOUCH, Touch(part="right_shoulder", kind="tap"))
        sim.tick(urgent=True)
        sim.run_for(3)
        mark = len(said)
        sim.feed(keys.PERCEPTION_SPEECH, Speech(text="stop", confidence=0.95))
        record = sim.tick(urgent=True)
        assert ("cancel", "quiz") in [(d.action, d.activity) for d in record.decisions]
        sim.run_for(10)
        assert any("stop the quiz here" in t for t in said[mark:]), said[mark:]
