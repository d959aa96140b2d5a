"""Block parameters, declared once as pydantic models: the loader's checks, the binding
on entry, the schema and the documentation all come from the models."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import pytest

from activities import ActivityStatus, BehaviorError
from activities.blocks import BLOCKS, Block
from activities.schema import json_schema
from activities.spec import CONTAINER_PARAMS, parse_text

HEAD = "name: x\noutcomes: [done]\nstates:\n  S:\n"
DOCS = Path(__file__).resolve().parents[2] / "docs" / "behaviors.md"


def _problem(state: str) -> str:
    with pytest.raises(BehaviorError) as caught:
        parse_text(HEAD + state, "x.yaml")
    return str(caught.value)


@pytest.mark.parametrize(
    ("state", "expected"),
    [
        (
            "    speak: {text: hi, priority: loud}\n",
            "x.yaml:5: state S: speak: parameter 'priority' must be string one of "
            "['normal', 'high'], not str 'loud'",
        ),
        (
            "    ask: {question: q, choices: [a, 3]}\n",
            "x.yaml:5: state S: ask: parameter 'choices' must be list of strings, "
            "not list ['a', 3]",
        ),
        (
            "    ask: {question: q, attempts: 2.5}\n",
            "x.yaml:5: state S: ask: parameter 'attempts' must be integer, not float 2.5",
        ),
        (
            "    wait: {seconds: soon}\n",
            "x.yaml:5: state S: wait: parameter 'seconds' must be number or null, not str 'soon'",
        ),
        (
            "    check: {value: 1, inn: [1]}\n",
            "x.yaml:5: state S: check: unknown parameter 'inn' "
            "(value, in, all_in, equals, at_least)",
        ),
        (
            "    iterator: {items: many, continue_on: [done], state: {A: {wait: {}}}}\n",
            "x.yaml:5: state S: iterator: parameter 'items' must be list or integer, "
            "not str 'many'",
        ),
        (
            "    concurrence:\n      outcomes: [done]\n      default_outcome: done\n"
            "      wait: sometimes\n      states: {A: {wait: {}}}\n",
            "x.yaml:8: state S: concurrence: parameter 'wait' must be string one of "
            "['match', 'any', 'all'], not str 'sometimes'",
        ),
    ],
)
def test_a_wrong_value_is_named_with_the_type_the_model_asks_for(state: str, expected: str) -> None:
    assert _problem(state).startswith(expected)


def test_problems_come_in_the_order_written_then_the_missing_ones() -> None:
    with pytest.raises(BehaviorError) as caught:
        parse_text(HEAD + "    ask: {loud: 1, timeout_s: ten}\n", "x.yaml")
    assert [p.split(": ", 2)[2] for p in caught.value.problems][:3] == [
        "ask: unknown parameter 'loud' (question, choices, correct, branch, timeout_s, "
        "attempts, key, retry_text)",
        "ask: parameter 'timeout_s' must be number, not str 'ten'",
        "ask: missing parameter 'question'",
    ]


def test_a_placeholder_is_accepted_for_a_parameter_of_any_type() -> None:
    spec = parse_text(
        HEAD + "    speak: {text: '{args.text}', priority: '{args.p}', volume: '{user.v}'}\n"
        "    transitions: {done: T}\n"
        "  T:\n    ask: {question: q, branch: '{args.b}', attempts: '{args.n}'}\n"
        "    transitions: {answered: done, no_answer: done}\n",
        "x.yaml",
    )
    assert spec.root.states["S"].params["priority"] == "{args.p}"


def test_a_required_parameter_written_as_a_placeholder_is_not_missing() -> None:
    spec = parse_text(
        HEAD + "    set_param: {name: '{args.name}', value: '{args.value}'}\n", "x.yaml"
    )
    # kept as written, to be bound on entry; without ``name`` the same state is refused
    assert spec.root.states["S"].params == {"name": "{args.name}", "value": "{args.value}"}
    assert _problem("    set_param: {value: '{args.value}'}\n") == (
        "x.yaml:5: state S: set_param: missing parameter 'name'"
    )


def test_the_schema_allows_a_placeholder_wherever_a_string_would_not_do() -> None:
    variants = json_schema()["$defs"]["state"]["oneOf"]
    speak = next(v for v in variants if "speak" in v["properties"])
    props = speak["properties"]["speak"]["properties"]
    assert props["text"] == {"type": "string", "description": "What to say; may use placeholders."}
    options = props["priority"]["anyOf"]
    assert options[0] == {"enum": ["normal", "high"], "type": "string"}
    assert options[1]["pattern"].startswith("^\\s*\\{")
    assert props["priority"]["default"] == "normal"
    assert [o.get("type") for o in props["volume"]["anyOf"]] == ["number", "null", "string"]
    check = next(v for v in variants if "check" in v["properties"])
    assert "in" in check["properties"]["check"]["properties"]  # the alias, as written


BOUND = """
name: bound
outcomes: [done]
states:
  WAIT:
    wait: {seconds: "{args.s}"}
    transitions: {done: SAY}
  SAY:
    speak: {text: "{args.n}", volume: "{user.volume}"}
    transitions: {done: done}
"""


def test_a_bound_value_is_validated_and_coerced_on_entry(make: Any) -> None:
    bench = make({"bound": BOUND})
    activity = bench.start(bench.create("bound", {"s": "2", "n": [1, 2, 3]}))
    bench.advance(activity, 1.5)
    assert not bench.said()  # "2" was bound and taken as 2 seconds
    assert bench.finish(activity, limit_s=30) is ActivityStatus.COMPLETED
    said = [c for c in bench.commands if c.channel == "speech"]
    assert said[-1].args["text"] == "1, 2 and 3"  # a list bound into text reads as text
    assert "volume" not in said[-1].args  # bound to nothing: the default (the rule decides)


def test_a_bound_value_that_does_not_fit_fails_the_activity_naming_it(make: Any) -> None:
    bench = make({"bound": BOUND})
    activity = bench.start(bench.create("bound", {"s": "soon", "n": 1}))
    assert bench.finish(activity, limit_s=30) is ActivityStatus.FAILED
    assert activity.result.error == (
        "WAIT: BehaviorError: wait: parameter 'seconds' must be number or null, "
        "not str 'soon' (bound from '{args.s}')"
    )


def test_values_with_no_placeholder_are_validated_once_and_copied_into_userdata(
    make: Any,
) -> None:
    bench = make(
        {
            "twice": """
            name: twice
            outcomes: [done]
            userdata: {n: 0}
            states:
              SET:
                set_data: {values: {seen: [a]}, add: {n: 1}}
                transitions: {done: LOOP}
              LOOP:
                check: {value: "{n}", at_least: 2}
                transitions: {met: done, not_met: SET}
            """
        }
    )
    activity = bench.start(bench.create("twice"))
    assert bench.finish(activity, limit_s=30) is ActivityStatus.COMPLETED
    node = activity.root.children()[0]
    assert isinstance(node, Block) and node.entered == 2
    assert node.bound() is node.bound()  # no placeholder: one validated instance
    assert activity.userdata["seen"] == ["a"]
    activity.userdata["seen"].append("b")  # the userdata's own copy
    assert node.bound().model_dump()["values"] == {"seen": ["a"]}


def _docs_rows() -> dict[str, str]:
    rows = re.findall(r"^\| `(\w+)` \| (.*?) \|", DOCS.read_text(), re.MULTILINE)
    return dict(rows)


def test_the_docs_name_every_parameter_of_every_block_and_container() -> None:
    rows = _docs_rows()
    models = {**{name: cls.PARAMS for name, cls in BLOCKS.items()}, **CONTAINER_PARAMS}
    for name, model in models.items():
        assert name in rows, f"docs/behaviors.md has no row for {name}"
        for field_name, field in model.model_fields.items():
            written = field.alias or field_name
            assert f"`{written}`" in rows[name], f"docs/behaviors.md: {name} lacks {written}"


def test_a_container_takes_a_placeholder_only_where_it_binds_one() -> None:
    parse_text(
        HEAD + "    iterator: {items: '{args.items}', continue_on: [done], "
        "state: {A: {wait: {seconds: 1}}}}\n",
        "x.yaml",
    )
    message = _problem(
        "    concurrence:\n      outcomes: [done]\n      default_outcome: done\n"
        "      wait: '{args.wait}'\n      states: {A: {wait: {}}}\n"
    )
    assert "concurrence: parameter 'wait' must be string one of" in message
    variants = json_schema()["$defs"]["state"]["oneOf"]
    guard = next(v for v in variants if "guard" in v["properties"])
    assert guard["properties"]["guard"]["properties"]["touch"]["type"] == "array"
