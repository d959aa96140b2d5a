"""Table 4's activity loading time measured on a real run of the controller stack."""

from __future__ import annotations

from dms.config import Settings
from dms.kernel import keys
from dms.kernel.expression import Priority
from dms.kernel.messages import Request, UserPerception
from sim.harness import Simulation
from sim.study import SessionObserver, command_handle

SETTINGS = {
    "controller": {"session_questions": 0, "question_every": 0, "feedback_probability": 0.0}
}


def _observed(sim: Simulation) -> SessionObserver:
    observer = SessionObserver()
    sim.decision_listeners.append(observer.on_decision)
    sim.command_listeners.append(
        lambda cmd, _now: observer.on_command(command_handle(sim, cmd), sim.t)
    )
    sim.tick_listeners.append(lambda _record: observer.on_tick(sim.t))
    return observer


def _start_jokes(busy_words: int) -> tuple[SessionObserver, float]:
    """Start jokes by request while the speech channel says ``busy_words`` words."""
    with Simulation(Settings.model_validate(SETTINGS), seed=3) as sim:
        observer = _observed(sim)
        sim.presence = UserPerception(present=True, user_id="alice", ready=True, engagement=None)
        sim.run_for(3.0)
        busy_s = 0.0
        if busy_words:
            text = " ".join(["word"] * busy_words)
            handle = sim.stack.expression.request(
                "test", "speech", "say", {"text": text}, sim.now(), Priority.HIGH
            )
            assert handle.command_id is not None
            busy_s = sim.robot.duration(sim.robot.log[-1][1])
        sim.feed(keys.REQUEST, Request(action="start", activity="jokes", by="test"))
        sim.run_for(busy_s + 5.0)
        return observer, busy_s


def test_load_time_is_the_feedback_round_on_a_free_channel() -> None:
    observer, _ = _start_jokes(0)
    assert observer.metrics.activities == 1
    assert len(observer.metrics.load_times) == 1
    assert 0.0 <= observer.metrics.load_times[0] <= 0.5


def test_load_time_includes_the_wait_for_a_busy_channel() -> None:
    observer, busy_s = _start_jokes(40)
    assert busy_s > 10.0
    assert observer.metrics.activities == 1
    (load,) = observer.metrics.load_times
    assert busy_s <= load <= busy_s + 0.5, (load, busy_s)  # the wait, then one tick
