"""The open format: round trips, the JSON Schema, bad files refused with file:line and state."""

from __future__ import annotations

import json
import shutil
import textwrap
from pathlib import Path

import pytest
import yaml

from activities import BehaviorError, BehaviorLibrary
from activities.blocks import BLOCKS
from activities.library import BEHAVIORS_DIR
from activities.schema import SCHEMA_PATH, json_schema
from activities.spec import parse_file, parse_text
from activities.synonyms import match_activity
from dms.kernel.activity_names import ACTIVITIES


@pytest.mark.parametrize("path", sorted(BEHAVIORS_DIR.glob("*.yaml")), ids=lambda p: p.stem)
def test_every_shipped_behavior_round_trips_without_loss(path: Path, tmp_path: Path) -> None:
    spec = parse_file(path)
    assert spec.to_dict() == yaml.safe_load(path.read_text())
    saved = tmp_path / path.name
    spec.save(saved)
    again = parse_file(saved)
    assert again.to_dict() == spec.to_dict()
    assert again.dump() == spec.dump()


def test_the_published_schema_is_the_generated_one() -> None:
    published = json.loads(SCHEMA_PATH.read_text())
    assert published == json_schema()
    variants = published["$defs"]["state"]["oneOf"]
    blocks = {next(iter(v["required"])) for v in variants}
    containers = {"state_machine", "sequence", "concurrence", "iterator", "guard", "behavior"}
    assert blocks == {*BLOCKS, *containers}


def _bad(tmp_path: Path, text: str, name: str = "bad") -> str:
    path = tmp_path / f"{name}.yaml"
    path.write_text(textwrap.dedent(text).lstrip())
    with pytest.raises(BehaviorError) as caught:
        BehaviorLibrary.load(tmp_path)
    return str(caught.value)


def test_unknown_block_is_refused_with_file_line_and_state(tmp_path: Path) -> None:
    message = _bad(
        tmp_path,
        """
        name: bad
        outcomes: [done]
        states:
          HELLO:
            speak: {text: hi}
            transitions: {done: FLY}
          FLY:
            levitate: {height: 3}
        """,
    )
    assert message.startswith(f"{tmp_path / 'bad.yaml'}:8: state FLY: unknown block 'levitate'")


def test_transition_to_a_missing_state(tmp_path: Path) -> None:
    message = _bad(
        tmp_path,
        """
        name: bad
        outcomes: [done]
        states:
          HELLO:
            speak: {text: hi}
            transitions: {done: NOWHERE}
        """,
    )
    assert "bad.yaml:6: state HELLO: transition 'done' goes to missing state 'NOWHERE'" in message


def test_unreachable_state_deep_inside(tmp_path: Path) -> None:
    message = _bad(
        tmp_path,
        """
        name: bad
        outcomes: [done]
        states:
          OUTER:
            state_machine:
              outcomes: [done]
              states:
                A:
                  speak: {text: a}
                B:
                  speak: {text: b}
        """,
    )
    assert "bad.yaml:10: state OUTER/B: unreachable state" in message


def test_wrong_parameter_type(tmp_path: Path) -> None:
    message = _bad(
        tmp_path,
        """
        name: bad
        outcomes: [done]
        states:
          ASK:
            ask:
              question: "Ready?"
              timeout_s: ten
            transitions: {answered: done, no_answer: done}
        """,
    )
    assert (
        "bad.yaml:7: state ASK: ask: parameter 'timeout_s' must be number, not str 'ten'" in message
    )


def test_cycle_of_behavior_references(tmp_path: Path) -> None:
    (tmp_path / "a.yaml").write_text(
        "name: a\noutcomes: [done]\nstates:\n  USE_B:\n    behavior: {name: b}\n"
    )
    (tmp_path / "b.yaml").write_text(
        "name: b\noutcomes: [done]\nstates:\n  USE_A:\n    behavior: {name: a}\n"
    )
    with pytest.raises(BehaviorError) as caught:
        BehaviorLibrary.load(tmp_path)
    message = str(caught.value)
    assert (
        f"{tmp_path / 'b.yaml'}:4: state USE_A: cycle of behavior references: a -> b -> a"
        in message
    )


def test_other_mistakes_are_named(tmp_path: Path) -> None:
    head = "name: x\noutcomes: [done]\nstates:\n"
    cases = {
        head + "  S:\n    speak: {txt: hi}\n": "unknown parameter 'txt'",
        head + "  S:\n    speak: {}\n": "missing parameter 'text'",
        head + "  S:\n    check: {value: 1}\n": "outcome 'met' leads nowhere",
        head + "  S: {speak: {text: a}, wait: {}}\n": "exactly one block",
        "name: x\noutcomes: [done]\nstates: [1, 2\n": "not valid YAML",
        head + "  S:\n    speak: {text: a}\n    transitions: {over: done}\n": "no outcome 'over'",
        "- just\n- a list\n": "a behavior file is a mapping",
    }
    for text, expected in cases.items():
        with pytest.raises(BehaviorError) as caught:
            parse_text(text, "x.yaml")
        assert expected in str(caught.value), text
        assert str(caught.value).startswith("x.yaml:")


def test_reload_keeps_the_previous_version_when_new_files_are_bad(tmp_path: Path) -> None:
    directory = tmp_path / "behaviors"
    shutil.copytree(BEHAVIORS_DIR, directory)
    library = BehaviorLibrary.load(directory)
    before = library.spec("jokes")
    jokes = directory / "jokes.yaml"
    jokes.write_text(jokes.read_text().replace("speak:", "shout:", 1))
    problems = library.reload()
    assert problems and "jokes.yaml" in problems[0] and "unknown block 'shout'" in problems[0]
    assert library.spec("jokes") is before
    jokes.write_text(jokes.read_text().replace("shout:", "speak:", 1))
    (directory / "extra.yaml").write_text(
        "name: extra\noutcomes: [done]\nstates:\n  HI:\n    speak: {text: hi}\n"
    )
    assert library.reload() == []
    assert "extra" in library.names and library.spec("jokes") is not before


def test_unknown_behavior_name(shipped: BehaviorLibrary) -> None:
    with pytest.raises(BehaviorError, match="no behavior named 'chess'"):
        shipped.spec("chess")


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("let's play the quiz", "quiz"),
        ("I want to do some brain training", "cognitive_stimulation"),
        ("cognitive stimulation please", "cognitive_stimulation"),
        ("Tell me a JOKE", "jokes"),
        ("what's the forecast", "weather"),
        ("play some music", "multimedia"),
        ("wait", "wait"),
        ("can you wait a moment", None),
        ("hello there", None),
        ("", None),
    ],
)
def test_synonyms_name_activities(text: str, expected: str | None) -> None:
    assert match_activity(text) == expected


def test_every_activity_is_named_by_its_own_name() -> None:
    for name in ACTIVITIES:
        assert match_activity(name) == name
        assert match_activity(name.replace("_", " ")) == name


def test_transitions_of_a_behavior_reference_are_checked(tmp_path: Path) -> None:
    (tmp_path / "inner.yaml").write_text(
        "name: inner\noutcomes: [won, lost]\nstates:\n  S:\n    speak: {text: hi}\n"
        "    transitions: {done: won}\n"
    )
    (tmp_path / "outer.yaml").write_text(
        "name: outer\noutcomes: [done]\nstates:\n  USE:\n    behavior: {name: inner}\n"
        "    transitions: {won: done, draw: done}\n"
    )
    with pytest.raises(BehaviorError) as caught:
        BehaviorLibrary.load(tmp_path)
    problems = caught.value.problems
    assert (
        f"{tmp_path / 'outer.yaml'}:4: state USE: behavior inner has no outcome 'draw'" in problems
    )
    assert f"{tmp_path / 'outer.yaml'}:4: state USE: outcome 'lost' leads nowhere" in problems
