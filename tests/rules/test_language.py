"""Semantics of DMSL: precedence, dangling else, Kleene logic, evaluate, sets, names."""

from __future__ import annotations

from typing import Any

import pytest

from dms.rules import RuleResult, RulesError, parse, rules_from_text
from dms.rules import nodes as n


def run(text: str, component: str = "C", **profiles: dict[str, Any]) -> RuleResult:
    return rules_from_text(text).evaluate(component, profiles)


def cond(expr: str) -> n.Expr:
    """The parsed expression of ``def x <expr>``."""
    return parse(f"def x {expr}").definitions[0].expr


# ------------------------------------------------------------------ precedence


def test_not_binds_looser_than_membership() -> None:
    u = n.Param(n.Profile.USER, "bondlevel")
    assert cond("not params.user.bondlevel in willingToBond") == n.Not(
        n.Member(u, n.Name("willingToBond"))
    )


def test_and_binds_tighter_than_or() -> None:
    a, b, c = n.Name("a"), n.Name("b"), n.Name("c")
    assert cond("a or b and c") == n.Or(a, n.And(b, c))
    assert cond("a and b or c") == n.Or(n.And(a, b), c)
    assert cond("(a or b) and c") == n.And(n.Or(a, b), c)


def test_not_binds_tighter_than_and() -> None:
    a, b = n.Name("a"), n.Name("b")
    assert cond("not a and b") == n.And(n.Not(a), b)
    assert cond("not (a and b)") == n.Not(n.And(a, b))


def test_or_and_are_left_associative() -> None:
    a, b, c = n.Name("a"), n.Name("b"), n.Name("c")
    assert cond("a or b or c") == n.Or(n.Or(a, b), c)
    assert cond("a and b and c") == n.And(n.And(a, b), c)


def test_comparisons_do_not_chain() -> None:
    with pytest.raises(RulesError, match=r"1:13: syntax error: unexpected '<'"):
        parse("def x 1 < 2 < 3")


def test_not_in_is_one_operator() -> None:
    t = n.Param(n.Profile.ENV, "time")
    assert cond("params.env.time not in free") == n.Member(t, n.Name("free"), negated=True)


def test_precedence_changes_the_decision() -> None:
    text = """
    def willing {3, 4, 5}
    component C [ if not params.user.bond in willing then activate "away" else activate "near" ]
    """
    assert run(text, user={"bond": 4}).activate == ("near",)
    assert run(text, user={"bond": 1}).activate == ("away",)


# --------------------------------------------------------------- dangling else


DANGLING = (
    'component C [ if params.user.a then if params.user.b then activate "x" else activate "y" ]'
)


def test_else_belongs_to_the_nearest_if() -> None:
    program = parse(DANGLING)
    statement = program.components[0].body[0]
    assert isinstance(statement, n.If) and statement.else_ is None
    inner = statement.then
    assert isinstance(inner, n.If) and inner.else_ == n.Activate("y")


def test_dangling_else_behaviour() -> None:
    text = DANGLING
    assert run(text, user={"a": False, "b": False}).activate == ()
    assert run(text, user={"a": True, "b": False}).activate == ("y",)
    assert run(text, user={"a": True, "b": True}).activate == ("x",)


def test_brackets_give_the_else_to_the_outer_if() -> None:
    text = (
        'component C [ if params.user.a then [ if params.user.b then activate "x" ] '
        'else activate "y" ]'
    )
    assert run(text, user={"a": False, "b": False}).activate == ("y",)
    assert run(text, user={"a": True, "b": False}).activate == ()


def test_a_block_of_one_statement_is_that_statement() -> None:
    assert parse('component C [ [ activate "a" ] ]') == parse('component C [ activate "a" ]')


# ------------------------------------------------------------------ Kleene


KLEENE = """
component C [
    if {expr} then activate "true"
    else if not ({expr}) then activate "false"
    else activate "unknown"
]
"""


@pytest.mark.parametrize(
    ("expr", "user", "outcome"),
    [
        ("not params.user.a", {}, "unknown"),
        ("not params.user.a", {"a": True}, "false"),
        ("params.user.a or params.user.b", {"a": True}, "true"),
        ("params.user.b or params.user.a", {"a": True}, "true"),
        ("params.user.a or params.user.b", {"a": False}, "unknown"),
        ("params.user.a or params.user.b", {"a": False, "b": False}, "false"),
        ("params.user.a and params.user.b", {"a": False}, "false"),
        ("params.user.b and params.user.a", {"a": False}, "false"),
        ("params.user.a and params.user.b", {"a": True}, "unknown"),
        ("params.user.a and params.user.b", {"a": True, "b": True}, "true"),
        ("params.user.n > 3", {}, "unknown"),
        ("params.user.n = params.user.m", {"n": 1}, "unknown"),
        ("params.user.n in {1, 2}", {}, "unknown"),
        ("params.user.n not in {1, 2}", {}, "unknown"),
        # values of a kind an operator cannot use are unknown too, not an error
        ("params.user.n > 3", {"n": "many"}, "unknown"),
        ("params.user.n = 1", {"n": True}, "unknown"),
        ("params.user.n = 1", {"n": "1"}, "unknown"),
        ("params.user.a", {"a": 7}, "unknown"),
    ],
)
def test_three_valued_logic(expr: str, user: dict[str, Any], outcome: str) -> None:
    assert run(KLEENE.format(expr=expr), user=user).activate == (outcome,)


def test_if_takes_else_when_condition_is_unknown_and_names_what_is_missing() -> None:
    text = 'component C [ if params.user.age > 80 then activate "old" else activate "other" ]'
    result = run(text)
    assert result.activate == ("other",)
    assert result.missing == ("user.age",)


def test_missing_is_sorted_and_unique() -> None:
    text = """component C [
        if params.user.b = 1 then activate "x"
        if params.user.a = 1 or params.user.b = 2 then activate "y"
    ]"""
    assert run(text).missing == ("user.a", "user.b")


def test_none_counts_as_missing() -> None:
    assert run(
        'component C [ if params.env.x = 1 then activate "a" ]', env={"x": None}
    ).missing == ("env.x",)


def test_short_circuit_does_not_look_up_the_right_side() -> None:
    text = 'component C [ if params.user.a or params.user.b then activate "x" ]'
    assert run(text, user={"a": True}).missing == ()


# ------------------------------------------------------------------ numbers


def test_ints_and_floats_compare_as_numbers() -> None:
    text = (
        'component C [ if params.user.x = 2 then activate "eq" '
        'if params.user.x >= 1.5 then activate "ge" ]'
    )
    assert run(text, user={"x": 2.0}).activate == ("eq", "ge")
    assert run(text, user={"x": 1}).activate == ()
    assert run(
        'component C [ if params.user.x < -0.5 then activate "neg" ]', user={"x": -1}
    ).activate == ("neg",)


def test_a_boolean_is_not_a_number() -> None:
    text = 'component C [ if params.user.x in {1} then activate "in" else activate "out" ]'
    assert run(text, user={"x": True}).activate == ("out",)
    assert run(text, user={"x": 1.0}).activate == ("in",)


# ------------------------------------------------------------- commands, chains


def test_commands_come_in_order_and_evaluate_splices() -> None:
    text = """
    component C [
        activate "first"
        evaluate D
        cancel "old"
        activate "last"
    ]
    component D [ activate "middle" evaluate E cancel "older" ]
    component E [ if params.robot.ok then activate "deep" ]
    """
    result = run(text, robot={"ok": True})
    assert result.activate == ("first", "middle", "deep", "last")
    assert result.cancel == ("older", "old")
    assert run(text).missing == ("robot.ok",)


def test_evaluate_may_refer_to_a_component_of_another_file(tmp_path: Any) -> None:
    from dms.rules import load_rules

    a = tmp_path / "a.dmsl"
    b = tmp_path / "b.dmsl"
    a.write_text("component A [ evaluate B ]\n", encoding="utf-8")
    b.write_text(
        'def yes true\ncomponent B [ if params.user.x then activate "b" ]\n', encoding="utf-8"
    )
    assert load_rules([a, b]).evaluate("A", {"user": {"x": True}}).activate == ("b",)


# --------------------------------------------------------------------- sets


def test_sets_of_strings_and_set_parameters() -> None:
    text = """
    def rooms {"kitchen", "hall"}
    component C [
        if params.robot.room in rooms then activate "known"
        if "quiz" in params.user.likes then activate "quiz"
        if params.user.likes = {"dance", "quiz"} then activate "same"
    ]
    """
    assert run(text, robot={"room": "hall"}, user={"likes": ["quiz", "dance"]}).activate == (
        "known",
        "quiz",
        "same",
    )
    assert run(text, robot={"room": "attic"}, user={"likes": []}).activate == ()


def test_empty_set_and_unusable_set_parameter() -> None:
    text = 'component C [ if params.user.x in {} then activate "in" else activate "out" ]'
    assert run(text, user={"x": 1}).activate == ("out",)
    text = 'component C [ if 1 in params.user.s then activate "in" else activate "no" ]'
    result = run(text, user={"s": [{"not": "a literal"}]})
    assert result.activate == ("no",)
    assert result.missing == ()


# ---------------------------------------------------------- named conditions


def test_named_conditions_and_constants() -> None:
    text = """
    def old params.user.age > limit
    def limit 80
    def tired params.robot.batterylevel < 20 or old
    component C [ if tired then activate "rest" else activate "play" ]
    """
    assert run(text, user={"age": 85}, robot={"batterylevel": 90}).activate == ("rest",)
    assert run(text, user={"age": 30}, robot={"batterylevel": 10}).activate == ("rest",)
    assert run(text, user={"age": 30}, robot={"batterylevel": 90}).activate == ("play",)
    result = run(text, robot={"batterylevel": 90})
    assert result.activate == ("play",)
    assert result.missing == ("user.age",)


def test_comments_and_string_escapes() -> None:
    text = """
    # a comment
    component C [ // another
        activate "say \\"hi\\"\\n" # trailing
    ]
    """
    assert run(text).activate == ('say "hi"\n',)


def test_keywords_are_lower_case_and_reserved() -> None:
    with pytest.raises(RulesError, match="syntax error"):
        parse("def if 1")
    assert parse("def IF 1").definitions[0].name == "IF"
    assert parse("def iffy 1").definitions[0].name == "iffy"


def test_undefined_component_raises_key_error() -> None:
    with pytest.raises(KeyError):
        rules_from_text('component C [ activate "a" ]').evaluate("D", {})


def test_params_that_are_not_mappings_are_empty() -> None:
    result = rules_from_text('component C [ if params.user.a then activate "a" ]').evaluate(
        "C",
        {"user": "oops"},  # type: ignore[dict-item]
    )
    assert result == RuleResult((), (), ("user.a",))
