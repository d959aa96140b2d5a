"""SMACH's own container tests (executive_smach ``smach_ros/test/state_machine.py``,
``sequence.py``, ``concurrence.py``) restated as behavior files with the same
expectations, and preemption requests: two in a row running the cleanup states, one during a
pause, one on a state already stopped or whose parent was preempted."""

from __future__ import annotations

from typing import Any

from activities import ActivityStatus
from activities.containers import StateMachine
from activities.engine import Node, Status
from dms.kernel.messages import Touch
from tests.activities.conftest import Bench

# SMACH's Setter writes a = 'A'; its Getter copies a into b.
SETTER = "set_data: {values: {a: A}}"
GETTER = 'set_data: {values: {b: "{a}"}}'


def _run(make: Any, text: str, seconds: float = 5) -> tuple[Bench, Any]:
    bench: Bench = make({"t": text})
    activity = bench.start(bench.create("t"))
    bench.advance(activity, seconds)
    return bench, activity


def _find(node: Node, name: str) -> Node:
    for child in node.children():
        if child.name == name:
            return child
        try:
            return _find(child, name)
        except KeyError:
            pass
    raise KeyError(name)


# ------------------------------------------------------------ state_machine.py


def test_state_machine_userdata(make: Any) -> None:
    _, activity = _run(
        make,
        f"""
        name: t
        outcomes: [done]
        states:
          SETTER: {{{SETTER}, output_keys: [a], transitions: {{done: GETTER}}}}
          GETTER: {{{GETTER}, input_keys: [a], output_keys: [b]}}
        """,
    )
    assert activity.result.outcome == "done"
    assert activity.result.data["a"] == "A" and activity.result.data["b"] == "A"


def test_state_machine_userdata_nesting(make: Any) -> None:
    _, activity = _run(
        make,
        f"""
        name: t
        outcomes: [done, aborted, preempted]
        states:
          SETTER: {{{SETTER}, transitions: {{done: GETTER}}}}
          GETTER: {{{GETTER}, transitions: {{done: NEST}}}}
          NEST:
            state_machine:
              outcomes: [done, aborted, preempted]
              states:
                ASSERTER:
                  check: {{value: "{{a|}}", equals: A}}
                  input_keys: [a]
                  transitions: {{met: done, not_met: aborted}}
            input_keys: [a]
        """,
    )
    assert activity.result.outcome == "done"
    assert activity.result.data["b"] == "A"


def test_state_machine_userdata_remapping(make: Any) -> None:
    _, activity = _run(
        make,
        f"""
        name: t
        outcomes: [done]
        states:
          SETTER: {{{SETTER}, output_keys: [a], remapping: {{a: x}}, transitions: {{done: GETTER}}}}
          GETTER:
            {GETTER}
            input_keys: [a]
            output_keys: [b]
            remapping: {{a: x, b: y}}
        """,
    )
    assert activity.result.outcome == "done"
    assert activity.result.data["x"] == "A" and activity.result.data["y"] == "A"


def test_state_machine_group_transitions(make: Any) -> None:
    """SECOND aborts (g2); the group's transitions send it to FAILSAUCE, which ends done."""
    _, activity = _run(
        make,
        """
        name: t
        outcomes: [succeeded, done]
        states:
          FIRST: {check: {value: 1, equals: 1}, transitions: {met: SECOND, not_met: FAILSAUCE}}
          SECOND: {check: {value: 2, equals: 1}, transitions: {met: THIRD, not_met: FAILSAUCE}}
          THIRD: {check: {value: 1, equals: 1}, transitions: {met: succeeded, not_met: FAILSAUCE}}
          FAILSAUCE: {set_data: {values: {}}}
        """,
    )
    assert activity.result.outcome == "done"


# ------------------------------------------------------------ sequence.py


def test_sequence_follows_the_connector_outcome(make: Any) -> None:
    _, activity = _run(
        make,
        """
        name: t
        outcomes: [done, not_met]
        states:
          SEQ:
            sequence:
              outcomes: [met, not_met, done]
              connector_outcome: met
              states:
                FIRST: {check: {value: 1, equals: 1}}
                SECOND: {check: {value: 1, equals: 1}}
                THIRD: {check: {value: 1, equals: 1}, transitions: {met: done}}
            transitions: {met: done}
        """,
    )
    assert activity.result.outcome == "done"
    assert _find(activity.root, "SEQ").kind == "sequence"


def test_sequence_stops_at_a_failure(make: Any) -> None:
    """SMACH's test_exception: the state after the one that failed is never run."""
    _, activity = _run(
        make,
        """
        name: t
        outcomes: [done]
        states:
          SEQ:
            sequence:
              outcomes: [done]
              connector_outcome: done
              states:
                OK: {set_data: {values: {}}}
                ERROR: {set_data: {values: {z: 1}}, output_keys: [y]}
                IGNORED: {set_data: {values: {a: A}}}
        """,
    )
    assert activity.status is ActivityStatus.FAILED
    assert "a" not in activity.result.data


# ------------------------------------------------------------ concurrence.py

CONCURRENCE = f"""
name: t
outcomes: [succeeded, done, preempted]
states:
  CC:
    concurrence:
      outcomes: [succeeded, done]
      default_outcome: done
      wait: WAIT
      outcome_map: MAP
      states:
        SETTER: {{{SETTER}}}
        GETTER:
          state_machine:
            outcomes: [done]
            states:
              COPY: {{{GETTER}, transitions: {{done: SLEEP}}}}
              SLEEP: {{wait: {{seconds: 1}}}}
"""


def _concurrence(wait: str, outcome_map: str) -> str:
    return CONCURRENCE.replace("WAIT", wait).replace("MAP", outcome_map)


def test_concurrence_waits_for_all_by_default_in_smach(make: Any) -> None:
    _, activity = _run(make, _concurrence("all", "{succeeded: {SETTER: done}}"))
    assert activity.result.outcome == "succeeded"
    assert _find(activity.root, "GETTER").outcome == "done"  # it ran to its end
    assert activity.result.data["a"] == "A" and activity.result.data["b"] == "A"


def test_concurrence_preempts_the_siblings(make: Any) -> None:
    """child_termination_cb = True: SETTER ends, GETTER is preempted and says so."""
    _, activity = _run(
        make, _concurrence("any", "{succeeded: {SETTER: done, GETTER: preempted}}"), 0
    )
    assert activity.result.outcome == "succeeded"
    assert activity.result.data["b"] == "A"


def test_concurrence_does_not_preempt(make: Any) -> None:
    _, activity = _run(make, _concurrence("all", "{succeeded: {SETTER: done, GETTER: done}}"))
    assert activity.result.outcome == "succeeded"


# ------------------------------------------------------------ preemption requests

CLEANUP = """
name: t
outcomes: [done]
states:
  A: {wait: {seconds: null}, transitions: {done: done, preempted: B}}
  B: {wait: {seconds: null}, transitions: {done: done, preempted: CS}}
  CS: {speak: {text: "stopping"}, transitions: {done: C}}
  C: {wait: {seconds: null}}
"""


def test_two_requests_run_the_cleanup_states_as_smach(make: Any) -> None:
    bench: Bench = make({"t": CLEANUP})
    activity = bench.create("t")
    entered: list[str] = []
    activity.runtime.on_enter = lambda node: entered.append(node.name)
    bench.start(activity)
    activity.root.preempt()
    bench.advance(activity, 0.5)
    assert activity.state_path == "B"
    activity.root.preempt()
    bench.advance(activity, 10)
    assert entered == ["t", "A", "B", "CS", "C"]
    assert bench.said() == ["stopping"]
    assert activity.status is ActivityStatus.RUNNING and activity.state_path == "C"


def test_a_request_during_pause_is_served_after_resume(make: Any) -> None:
    bench: Bench = make({"t": CLEANUP})
    activity = bench.start(bench.create("t"))
    activity.pause(bench.now)
    activity.root.preempt()
    bench.advance(activity, 2)
    assert activity.state_path == "A"
    activity.resume(bench.now)
    bench.advance(activity, 0.5)
    assert activity.state_path == "B"


def test_a_request_on_a_state_its_guard_stopped_is_cleared(make: Any) -> None:
    bench: Bench = make(
        {
            "t": """
            name: t
            outcomes: [done]
            states:
              GAME:
                guard:
                  touch: [left_shoulder]
                  outcome: touched
                  state: {W: {wait: {seconds: null}}}
                transitions: {touched: GAME}
            """
        }
    )
    activity = bench.start(bench.create("t"))
    w = _find(activity.root, "W")
    w.preempt()
    assert activity.deliver(Touch(part="left_shoulder", kind="tap"))
    bench.advance(activity, 0.5)  # the guard fires and stops W before W's tick
    assert not w.preempt_requested
    bench.advance(activity, 0.5)
    assert w.status is Status.RUNNING and w.entered == 2
    assert activity.state_path == "GAME/W"


def test_a_request_on_a_state_whose_parent_was_preempted_is_served_once(make: Any) -> None:
    bench: Bench = make(
        {
            "t": """
            name: t
            outcomes: [done]
            userdata: {rounds: 0}
            states:
              LOOP:
                state_machine:
                  outcomes: [done]
                  states: {L: {wait: {seconds: null}}}
                transitions: {preempted: COUNT}
              COUNT: {set_data: {add: {rounds: 1}}, transitions: {done: LOOP}}
            """
        }
    )
    activity = bench.start(bench.create("t"))
    loop = _find(activity.root, "LOOP")
    assert isinstance(loop, StateMachine)
    leaf = _find(activity.root, "L")
    leaf.preempt()
    loop.preempt()  # the same tick: one preemption
    bench.advance(activity, 2)
    assert activity.userdata["rounds"] == 1
    assert leaf.status is Status.RUNNING and leaf.entered == 2
    assert not leaf.preempt_requested
