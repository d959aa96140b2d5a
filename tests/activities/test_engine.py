"""SMACH parity: containers, userdata, preemption, pause/resume at every depth, guards."""

from __future__ import annotations

from datetime import timedelta
from typing import Any

import pytest

from activities import ActivityStatus
from activities.containers import StateMachine
from activities.engine import PREEMPTED, Status
from dms.kernel.messages import ScreenChoice, Speech, Touch
from tests.activities.conftest import Bench, FakeRules

THREE_LEVELS = """
name: deep
outcomes: [done]
states:
  ONE:
    state_machine:
      outcomes: [done]
      states:
        TWO:
          state_machine:
            outcomes: [done]
            states:
              THREE:
                speak: {text: "deep down here we speak a long sentence of many words"}
                transitions: {done: AFTER}
              AFTER:
                wait: {seconds: 10}
    transitions: {done: LAST}
  LAST:
    speak: {text: "the end"}
"""


def test_nested_machines_run_in_order_and_report_the_path(make: Any) -> None:
    bench: Bench = make({"deep": THREE_LEVELS})
    activity = bench.start(bench.create("deep"))
    assert activity.state_path == "ONE/TWO/THREE"
    bench.run_until(activity, lambda: activity.state_path == "ONE/TWO/AFTER")
    bench.run_until(activity, lambda: activity.state_path == "LAST")
    assert bench.finish(activity) is ActivityStatus.COMPLETED
    assert activity.result.outcome == "done"
    assert bench.said() == ["deep down here we speak a long sentence of many words", "the end"]


def test_userdata_input_output_keys_and_remapping(make: Any) -> None:
    bench: Bench = make(
        {
            "ud": """
            name: ud
            outcomes: [done]
            userdata: {total: 5, shown: none}
            states:
              INNER:
                state_machine:
                  outcomes: [done]
                  userdata: {count: 0}
                  states:
                    ADD:
                      set_data: {add: {count: 2}}
                      transitions: {done: COPY}
                    COPY:
                      set_data: {values: {result: "{count}"}}
                input_keys: [count]
                output_keys: [result]
                remapping: {count: total, result: shown}
                transitions: {done: SAY}
              SAY:
                speak: {text: "total {total} shown {shown}"}
            """
        }
    )
    activity = bench.start(bench.create("ud"))
    assert bench.finish(activity) is ActivityStatus.COMPLETED
    # count came in as total (5), +2 inside; result went out as shown; total unchanged outside
    assert bench.said() == ["total 5 shown 7"]
    assert activity.result.data["shown"] == 7
    assert "count" not in activity.result.data


def test_a_state_cannot_read_an_undeclared_key(make: Any) -> None:
    bench: Bench = make(
        {
            "closed": """
            name: closed
            outcomes: [done]
            userdata: {secret: 42, visible: 1}
            states:
              SAY:
                speak: {text: "I see {visible} and {secret|nothing}"}
                input_keys: [visible]
            """
        }
    )
    activity = bench.start(bench.create("closed"))
    bench.finish(activity)
    assert bench.said() == ["I see 1 and nothing"]


CONCURRENT = """
name: conc
outcomes: [short, both, other]
states:
  BOTH:
    concurrence:
      outcomes: [short, both, other]
      default_outcome: other
      outcome_map:
        short: {FAST: done, SLOW: preempted}
        both: {FAST: done, SLOW: done}
      states:
        FAST:
          wait: {seconds: 2}
        SLOW:
          wait: {seconds: 20}
"""


def test_concurrence_outcome_map_and_default(make: Any) -> None:
    bench: Bench = make({"conc": CONCURRENT})
    activity = bench.start(bench.create("conc"))
    bench.advance(activity, 5)
    assert activity.state_path == "BOTH/SLOW"
    assert bench.finish(activity) is ActivityStatus.COMPLETED
    assert activity.result.outcome == "both"


def test_preemption_inside_a_concurrence_reaches_one_branch(make: Any) -> None:
    bench: Bench = make({"conc": CONCURRENT})
    activity = bench.start(bench.create("conc"))
    bench.advance(activity, 3)
    concurrence = _node(activity.root, "BOTH")
    slow = concurrence.states["SLOW"]
    slow.preempt()
    bench.advance(activity, 0.5)
    assert slow.outcome == PREEMPTED
    assert activity.status is ActivityStatus.COMPLETED
    assert activity.result.outcome == "short"


def test_preempting_the_whole_concurrence_stops_every_branch(make: Any) -> None:
    bench: Bench = make({"conc": CONCURRENT})
    activity = bench.start(bench.create("conc"))
    concurrence = _node(activity.root, "BOTH")
    concurrence.preempt()
    bench.advance(activity, 0.5)
    assert all(s.status is Status.INVALID for s in concurrence.states.values())
    assert concurrence.outcome == PREEMPTED
    assert activity.result.outcome == PREEMPTED


def test_preemption_right_after_start_is_not_lost(make: Any) -> None:
    bench: Bench = make({"deep": THREE_LEVELS})
    activity = bench.create("deep")
    activity.root.preempt()  # before the first tick: SMACH loses this one
    activity.start(bench.now)
    assert activity.status is ActivityStatus.COMPLETED
    assert activity.result.outcome == PREEMPTED
    assert bench.commands == []


def test_preemption_reaches_the_deepest_state_and_works_twice(make: Any) -> None:
    bench: Bench = make(
        {
            "again": """
            name: again
            outcomes: [done]
            userdata: {rounds: 0}
            states:
              LOOP:
                state_machine:
                  outcomes: [done]
                  states:
                    INNER:
                      state_machine:
                        outcomes: [done]
                        states:
                          TALK:
                            speak: {text: "a very long story that never seems to end at all"}
                transitions: {done: END, preempted: COUNT}
              COUNT:
                set_data: {add: {rounds: 1}}
                transitions: {done: LOOP}
              END:
                speak: {text: "end"}
            """
        }
    )
    activity = bench.start(bench.create("again"))
    loop = _node(activity.root, "LOOP")
    for expected in (1, 2, 3):
        assert activity.state_path == "LOOP/INNER/TALK"
        talking = bench.expression.active("speech")
        assert talking is not None
        loop.preempt()
        loop.preempt()  # asked twice before the tick: one preemption
        bench.advance(activity, 0.5)
        assert talking.status.value == "interrupted"
        assert activity.userdata["rounds"] == expected
    assert activity.status is ActivityStatus.RUNNING


def test_iterator_runs_once_per_item_and_breaks(make: Any) -> None:
    bench: Bench = make(
        {
            "it": """
            name: it
            outcomes: [done, found]
            states:
              EACH:
                iterator:
                  items: [apple, pear, plum, fig]
                  item_key: fruit
                  index_key: n
                  continue_on: [not_met]
                  break_on: {met: found}
                  exhausted: done
                  state:
                    BODY:
                      state_machine:
                        outcomes: [met, not_met]
                        states:
                          SAY:
                            speak: {text: "{n}: {fruit}"}
                            transitions: {done: TEST}
                          TEST:
                            check: {value: "{fruit}", equals: plum}
            """
        }
    )
    activity = bench.start(bench.create("it"))
    bench.finish(activity)
    assert bench.said() == ["1: apple", "2: pear", "3: plum"]
    assert activity.result.outcome == "found"


def test_a_machine_entered_again_gives_its_states_its_new_userdata(make: Any) -> None:
    """A machine with declared keys starts each run on fresh userdata; its states,
    entered again, read and write that, not the last run's."""
    bench: Bench = make(
        {
            "twice": """
            name: twice
            outcomes: [done]
            states:
              EACH:
                iterator:
                  items: [1, 2, 3]
                  item_key: round
                  continue_on: [done]
                  exhausted: done
                  state:
                    INNER:
                      state_machine:
                        outcomes: [done]
                        userdata: {count: 0}
                        states:
                          ADD:
                            set_data: {add: {count: 2}}
                            transitions: {done: SAY}
                          SAY:
                            speak: {text: "round {round}: {count}"}
                      input_keys: [round]
            """
        }
    )
    activity = bench.start(bench.create("twice"))
    assert bench.finish(activity) is ActivityStatus.COMPLETED
    assert bench.said() == ["round 1: 2", "round 2: 2", "round 3: 2"]


# ------------------------------------------------------------------ pause and resume


@pytest.mark.parametrize("depth_path", ["ONE/TWO/THREE", "ONE/TWO/AFTER", "LAST"])
def test_pause_and_resume_at_every_depth_restart_what_was_said(make: Any, depth_path: str) -> None:
    bench: Bench = make({"deep": THREE_LEVELS})
    activity = bench.start(bench.create("deep"))
    bench.run_until(activity, lambda: activity.state_path == depth_path)
    said_before = len(bench.said())
    bench.advance(activity, 0.5)
    activity.pause(bench.now)
    assert activity.status is ActivityStatus.PAUSED
    assert bench.expression.pending("activity:deep") == []  # commands withdrawn
    bench.advance(activity, 60)  # nothing moves while paused
    assert activity.state_path == depth_path
    assert len(bench.said()) == said_before
    activity.resume(bench.now)
    assert activity.state_path == depth_path  # history: the same state again
    if depth_path != "ONE/TWO/AFTER":
        assert len(bench.said()) == said_before + 1  # said again from the start
        assert bench.said()[-1] == bench.said()[-2]
    assert bench.finish(activity) is ActivityStatus.COMPLETED


def test_a_wait_keeps_its_remaining_time_across_a_pause(make: Any) -> None:
    bench: Bench = make({"deep": THREE_LEVELS})
    activity = bench.start(bench.create("deep"))
    bench.run_until(activity, lambda: activity.state_path == "ONE/TWO/AFTER")
    entered = bench.now
    bench.advance(activity, 4)
    activity.pause(bench.now)
    bench.advance(activity, 100)
    activity.resume(bench.now)
    bench.run_until(activity, lambda: activity.state_path == "LAST")
    waited = (bench.now - entered).total_seconds() - 100
    assert 9.5 <= waited <= 11


def test_an_ask_interrupted_by_a_pause_is_asked_again(bench: Bench) -> None:
    activity = bench.start(bench.create("quiz"))
    bench.run_until(activity, lambda: activity.state_path.endswith("ASK"))
    question = bench.last_said()
    activity.pause(bench.now)
    activity.resume(bench.now)
    assert bench.last_said() == question
    answer = activity.userdata["question"]["answer"]
    assert activity.deliver(Speech(text=f"I think it is {answer}", confidence=0.9))
    bench.run_until(activity, lambda: activity.userdata["score"] == 1, limit_s=20)
    assert bench.said()[-1].startswith("Correct!")


# ------------------------------------------------------------------ guards and decisions

GUARDED = """
name: guarded
outcomes: [done, touched, heard, late]
states:
  GUARD:
    guard:
      touch: [left_shoulder]
      keywords: [stop game]
      timer_s: 30
      outcome: fired
      state:
        WORK:
          state_machine:
            outcomes: [done]
            states:
              TALK:
                speak: {text: "one two three four five six seven eight nine ten"}
                transitions: {done: IDLE}
              IDLE:
                wait: {seconds: 100}
    transitions: {fired: AFTER}
  AFTER:
    speak: {text: "stopped"}
    transitions: {done: touched}
"""


def test_guard_stops_its_content_on_a_touch(make: Any) -> None:
    bench: Bench = make({"guarded": GUARDED})
    activity = bench.start(bench.create("guarded"))
    talking = bench.expression.active("speech")
    assert not activity.deliver(Touch(part="head", kind="tap"))
    assert activity.deliver(Touch(part="left_shoulder", kind="tap"))
    bench.advance(activity, 0.5)
    assert talking is not None and talking.status.value == "interrupted"
    assert bench.finish(activity) is ActivityStatus.COMPLETED
    assert bench.said()[-1] == "stopped"


def test_guard_fires_on_a_keyword_and_on_its_timer(make: Any) -> None:
    bench: Bench = make({"guarded": GUARDED})
    activity = bench.start(bench.create("guarded"))
    assert not activity.deliver(Speech(text="let's go on", confidence=0.9))
    assert activity.deliver(Speech(text="please stop game now", confidence=0.9))
    bench.advance(activity, 0.5)
    assert activity.state_path == "AFTER"

    activity = bench.start(bench.create("guarded"))
    started = bench.now
    bench.run_until(activity, lambda: activity.state_path == "AFTER")
    assert 29.5 <= (bench.now - started).total_seconds() <= 31


def test_a_paused_activity_takes_no_event(make: Any) -> None:
    bench: Bench = make({"guarded": GUARDED})
    activity = bench.start(bench.create("guarded"))
    activity.pause(bench.now)
    assert not activity.deliver(Touch(part="left_shoulder", kind="tap"))
    activity.resume(bench.now)
    assert activity.deliver(Touch(part="left_shoulder", kind="tap"))


DECIDING = """
name: deciding
outcomes: [done]
states:
  CHOOSE:
    decide: {component: Pick, outcomes: [left, right], default: right}
    transitions: {left: LEFT, right: RIGHT}
  LEFT:
    speak: {text: "left"}
  RIGHT:
    speak: {text: "right"}
"""


def test_decision_state_follows_the_rule_activation(make: Any) -> None:
    bench: Bench = make({"deciding": DECIDING})
    bench.rules = FakeRules({"Pick": ["nonsense", "left", "right"]})
    bench.finish(bench.start(bench.create("deciding")))
    assert bench.said() == ["left"]
    assert bench.rules.asked == ["Pick", "VoiceSettings"]  # the speech asks for its volume


def test_decision_state_uses_its_default_without_a_rule(make: Any) -> None:
    bench: Bench = make({"deciding": DECIDING})
    bench.finish(bench.start(bench.create("deciding")))
    bench.rules = FakeRules({"Other": ["left"]})
    bench.finish(bench.start(bench.create("deciding")))
    bench.rules = FakeRules({"Pick": ["up"]})  # activates no outcome
    bench.finish(bench.start(bench.create("deciding")))
    assert bench.said() == ["right", "right", "right"]


def test_behavior_reference_runs_another_file_as_a_state(make: Any) -> None:
    bench: Bench = make(
        {
            "outer": """
            name: outer
            outcomes: [done]
            states:
              FIRST:
                behavior: {name: inner}
                transitions: {finished: LAST}
              LAST:
                speak: {text: "outer end"}
            """,
            "inner": """
            name: inner
            outcomes: [finished]
            states:
              HI:
                speak: {text: "inner {user.name}"}
                transitions: {done: finished}
            """,
        }
    )
    activity = bench.start(bench.create("outer"))
    assert activity.state_path == "FIRST/HI"
    bench.finish(activity)
    assert bench.said() == ["inner Ana", "outer end"]


def test_cancel_stops_every_depth_and_is_final(make: Any) -> None:
    bench: Bench = make({"deep": THREE_LEVELS})
    activity = bench.start(bench.create("deep"))
    activity.cancel(bench.now)
    assert activity.status is ActivityStatus.CANCELLED
    assert bench.expression.pending() == []
    assert activity.tick(bench.now + timedelta(seconds=1)) is ActivityStatus.CANCELLED
    activity.pause(bench.now)
    activity.resume(bench.now)
    assert activity.status is ActivityStatus.CANCELLED
    assert activity.state_path == ""


def test_structure_describes_nesting_and_the_active_path(bench: Bench) -> None:
    activity = bench.start(bench.create("quiz"))
    bench.run_until(activity, lambda: activity.state_path.endswith("ASK"))
    structure = activity.structure()
    assert structure["active_path"] == "GAME/ROUNDS/ROUND/ASK"
    game = next(s for s in structure["root"]["states"] if s["name"] == "GAME")
    assert game["kind"] == "guard" and game["active"]
    rounds = game["states"][0]
    assert rounds["kind"] == "iterator"
    assert rounds["states"][0]["kind"] == "state_machine"
    assert structure["root"]["transitions"]["INTRO"] == {"done": "PICK"}


def _node(root: Any, name: str) -> Any:
    assert isinstance(root, StateMachine)
    return root.states[name]


def test_screen_choice_answers_a_question(bench: Bench) -> None:
    activity = bench.start(bench.create("quiz"))
    bench.run_until(activity, lambda: activity.state_path.endswith("ASK"))
    wrong = next(
        c
        for c in activity.userdata["question"]["choices"]
        if c != activity.userdata["question"]["answer"]
    )
    assert activity.deliver(ScreenChoice(choice=wrong))
    bench.advance(activity, 1)
    assert activity.userdata["score"] == 0
    assert activity.userdata["answer"] == wrong
    assert "right answer was" in bench.last_said()


def test_a_block_that_breaks_fails_its_activity_with_the_reason(make: Any) -> None:
    bench: Bench = make(
        {
            "broken": """
            name: broken
            outcomes: [done]
            userdata: {a: 1}
            states:
              WRITE:
                set_data: {values: {b: 2}}
                input_keys: [a]
                output_keys: [a]
            """
        }
    )
    activity = bench.start(bench.create("broken"))
    assert activity.status is ActivityStatus.FAILED
    assert activity.result.error is not None
    assert activity.result.error.startswith("WRITE: KeyError")
    assert "b is not an output key" in activity.result.error
