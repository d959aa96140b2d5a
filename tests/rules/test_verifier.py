"""Every check of the DMSL verifier, each with its FILE:LINE:COL: message."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from dms.rules import (
    ParameterSchema,
    Problem,
    RulesError,
    check_files,
    check_outcomes,
    load_rules,
    rules_from_text,
)

Write = Callable[..., Path]


def problems(write: Write, text: str, schema: ParameterSchema | None = None) -> list[str]:
    """Problems of ``text`` as lines, with the file name replaced by F."""
    path = write(text)
    return [str(p).replace(str(path), "F") for p in check_files([path], schema)]


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        (
            "component C [\n  if params.user.a then\n]",
            "F:3:1: syntax error: unexpected ']'; "
            "expected '[', 'activate', 'cancel', 'evaluate', 'if'",
        ),
        ("def x 1 +", "F:1:9: syntax error: unexpected character '+'"),
        ("def x", "F:1:6: syntax error: unexpected end of file; expected "),
        ('component C [ activate "open ]', "F:1:24: syntax error: unexpected character '\"'"),
        ("def x params.user", "F:1:7: 'params.user': write params.user.NAME"),
        ("def x params.usr.age", "F:1:14: unknown profile 'usr' (use user, robot or env)"),
        ('component C [ activate "\\q" ]', "F:1:25: unknown escape '\\q' in string"),
        ("def x 1e999", "F:1:7: number 1e999 is too large"),
    ],
)
def test_syntax_errors_have_line_and_column(write: Write, text: str, expected: str) -> None:
    found = problems(write, text)
    assert len(found) == 1
    assert found[0].startswith(expected)


def test_unknown_names_with_suggestions(write: Write) -> None:
    text = """def willingToBond {3, 4}
component C [
    if params.user.bond in willingToBnd then activate "a"
    if D then activate "b"
]
component D [ activate "d" ]
"""
    assert problems(write, text) == [
        "F:3:28: unknown name 'willingToBnd'; did you mean 'willingToBond'?",
        "F:4:8: unknown name 'D'; 'D' is a component (use evaluate)",
    ]


def test_duplicates(write: Write) -> None:
    text = 'def a 1\ndef a 2\ncomponent C [ activate "x" ]\ncomponent C [ activate "y" ]\n'
    assert problems(write, text) == [
        "F:2:1: duplicate definition 'a' (first at F:1:1)",
        "F:4:1: duplicate component 'C' (first at F:3:1)",
    ]


def test_duplicates_across_files(write: Write) -> None:
    first = write('component C [ activate "x" ]\n', "a.dmsl")
    second = write('component C [ activate "y" ]\n', "b.dmsl")
    assert [str(p) for p in check_files([first, second])] == [
        f"{second}:1:1: duplicate component 'C' (first at {first}:1:1)"
    ]


def test_evaluate_unknown_and_cycles(write: Write) -> None:
    text = """def limit 3
component A [ activate "a" evaluate B ]
component B [ evaluate A ]
component C [ evaluate Bb evaluate limit ]
component D [ activate "d" evaluate D ]
"""
    assert problems(write, text) == [
        "F:3:15: evaluate cycle: A -> B -> A",
        "F:4:15: evaluate of unknown component 'Bb'; did you mean 'B'?",
        "F:4:27: evaluate of unknown component 'limit'; 'limit' is a def, not a component",
        "F:5:28: evaluate cycle: D -> D",
    ]


def test_definition_cycles(write: Write) -> None:
    text = 'def a b or params.user.x\ndef b not a\ncomponent C [ if a then activate "x" ]\n'
    assert problems(write, text) == ["F:2:11: definition cycle: a -> b -> a"]


@pytest.mark.parametrize(
    ("condition", "expected"),
    [
        ('params.user.name < "m"', "F:1:37: type error: '<' needs numbers, got a string"),
        ("params.user.x >= {1, 2}", "F:1:35: type error: '>=' needs numbers, got a set"),
        ("params.user.x in 3", "F:1:35: type error: 'in' needs a set on its right, got a number"),
        ('params.user.x not in "abc"', "F:1:39: type error: 'not in' needs a set on its right"),
        ("{1} in {2}", "F:1:18: type error: 'in' needs a value on its left, got a set"),
        ('"a" in {1, 2}', "F:1:18: type error: a string is never in a set of numbers"),
        (
            'params.user.x = 1 and "yes"',
            "F:1:40: type error: 'and' needs true or false, got a string",
        ),
        ("not 3", "F:1:22: type error: 'not' needs true or false, got a number"),
        ('1 = "1"', "F:1:18: type error: '=' compares a number with a string"),
        ("true != 0", "F:1:18: type error: '!=' compares true or false with a number"),
        ("size", "F:1:18: type error: condition must be true or false, got a number"),
    ],
)
def test_type_errors(write: Write, condition: str, expected: str) -> None:
    text = f'component C [ if {condition} then activate "x" ]\ndef size 3\n'
    found = problems(write, text)
    assert found, condition
    assert found[0].startswith(expected)


def test_schema_catches_unknown_parameters_and_kinds(write: Write) -> None:
    schema = ParameterSchema(user={"age": "number", "name": "string"}, env={"time": "number"})
    text = """component C [
    if params.user.agee > 80 then activate "old"
    if params.user.name > 3 then activate "late"
    if params.robot.batterylevel < 10 then activate "low"
    if params.env.time in {"morning"} then activate "m"
]
"""
    assert problems(write, text, schema) == [
        "F:2:8: unknown parameter params.user.agee; did you mean 'age'?",
        "F:3:8: type error: '>' needs numbers, got a string",
        "F:4:8: unknown parameter params.robot.batterylevel",
        "F:5:8: type error: a number is never in a set of strings",
    ]
    assert problems(write, text) == []  # without a schema every parameter may exist


def test_constant_conditions_and_dead_branches(write: Write) -> None:
    text = """def limit 3
component C [
    if limit > 2 then activate "a" else activate "never"
    if params.user.x or true then activate "b"
    if false and params.user.x then activate "never"
]
"""
    assert problems(write, text) == [
        "F:3:8: condition is always true",
        "F:3:41: this branch can never run",
        "F:4:8: condition is always true",
        "F:5:8: condition is never true",
        "F:5:37: this branch can never run",
    ]


def test_conditions_decided_by_the_enclosing_ones(write: Write) -> None:
    text = """def old params.user.age > 80
component C [
    if old then [
        if params.user.age > 80 then activate "a"
        if not old then activate "never"
    ] else [
        if old then activate "never"
        if not old then activate "maybe"
    ]
]
"""
    assert problems(write, text) == [
        "F:4:12: condition is always true here (the enclosing conditions decide it)",
        "F:5:12: condition is never true here (the enclosing conditions decide it)",
        "F:5:25: this branch can never run",
        "F:7:12: condition is never true here (the enclosing conditions decide it)",
        "F:7:21: this branch can never run",
    ]


def test_else_of_an_unknown_condition_is_not_dead(write: Write) -> None:
    # `if a` takes its else when a is unknown, so `not a` may be unknown there too.
    text = """component C [
    if params.user.a then activate "x"
    else if not params.user.a then activate "y"
    else activate "z"
]
"""
    assert problems(write, text) == []


def test_components_that_never_activate(write: Write) -> None:
    text = """component Empty [ ]
component Cancels [ cancel "x" ]
component Dead [ if false then activate "x" ]
component Via [ evaluate Cancels ]
component Fine [ evaluate Sometimes ]
component Sometimes [ if params.user.x then activate "x" ]
"""
    assert problems(write, text) == [
        "F:1:1: component 'Empty' never activates anything",
        "F:2:1: component 'Cancels' never activates anything",
        "F:3:1: component 'Dead' never activates anything",
        "F:3:21: condition is never true",
        "F:3:32: this branch can never run",
        "F:4:1: component 'Via' never activates anything",
    ]


def test_check_outcomes_follows_evaluate() -> None:
    rules = rules_from_text(
        'component S [ if params.user.x then activate "go" else evaluate T ]\n'
        'component T [ activate "stay" activate "fly" ]',
        file="f.dmsl",
    )
    assert check_outcomes(rules, "S", {"go", "stay", "fly"}) == []
    found = check_outcomes(rules, "S", ["go", "stay"])
    assert [str(p) for p in found] == [
        'f.dmsl:2:31: activation "fly" of S is not an outcome of the state (outcomes: "go", "stay")'
    ]
    assert check_outcomes(rules, "Unknown", ["go"]) == []


def test_unreadable_and_non_utf8_files_are_problems(tmp_path: Path) -> None:
    missing = tmp_path / "missing.dmsl"
    binary = tmp_path / "binary.dmsl"
    binary.write_bytes(b"\xff\xfe component")
    found = check_files([missing, binary])
    assert [(p.file, p.line, p.column) for p in found] == [
        (str(missing), 1, 1),
        (str(binary), 1, 1),
    ]
    assert "cannot read" in found[0].message
    assert "not UTF-8" in found[1].message


def test_load_rules_raises_with_every_problem(write: Write) -> None:
    path = write('component C [ if x then activate "a" ]\ncomponent C [ activate "b" ]\n')
    with pytest.raises(RulesError) as caught:
        load_rules([path])
    assert len(caught.value.problems) == 2
    assert str(caught.value) == f"{path}:1:18: unknown name 'x' (and 1 more)"


def test_problem_text_and_caret_excerpt(write: Write) -> None:
    path = write('component C [\n\tif params.user.age > "old" then activate "a"\n]\n')
    (problem,) = check_files([path])
    assert isinstance(problem, Problem)
    assert str(problem) == f"{path}:2:23: type error: '>' needs numbers, got a string"
    assert (
        problem.excerpt()
        == '\tif params.user.age > "old" then activate "a"\n\t                     ^'
    )
    # without the source line kept, the excerpt reads the file
    bare = Problem(problem.file, problem.line, problem.column, problem.message)
    assert bare == problem
    assert bare.excerpt() == problem.excerpt()
    assert Problem("nowhere.dmsl", 1, 1, "x").excerpt() == ""


def test_schema_file_errors(tmp_path: Path) -> None:
    bad = tmp_path / "schema.json"
    bad.write_text('{"user": {"age": "integer"}}', encoding="utf-8")
    with pytest.raises(RulesError, match=r"schema.json:1:1: invalid schema: user.age"):
        ParameterSchema.load(bad)
    bad.write_text("{", encoding="utf-8")
    with pytest.raises(RulesError, match=r"schema.json:1:2: schema is not JSON"):
        ParameterSchema.load(bad)
    with pytest.raises(RulesError, match="cannot read schema"):
        ParameterSchema.load(tmp_path / "none.json")
    good = tmp_path / "good.json"
    good.write_text(ParameterSchema(user={"age": "number"}).dump(), encoding="utf-8")
    assert ParameterSchema.load(good).user == {"age": "number"}
