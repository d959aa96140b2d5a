"""Property tests: pretty-print round trip, and a parser that only raises RulesError."""

from __future__ import annotations

import math

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dms.rules import RulesError, parse, rules_from_text
from dms.rules import nodes as n
from dms.rules.parser import KEYWORDS
from dms.rules.printer import pretty

names = st.from_regex(r"[A-Za-z_][A-Za-z0-9_]{0,6}", fullmatch=True).filter(
    lambda name: name not in KEYWORDS and name != "params"
)
param_names = st.from_regex(r"[A-Za-z_][A-Za-z0-9_]{0,6}", fullmatch=True)
texts = st.text(max_size=8)
numbers = st.one_of(
    st.integers(min_value=-(10**20), max_value=10**20),
    st.floats(allow_nan=False, allow_infinity=False),
)
literals: st.SearchStrategy[n.Literal] = st.one_of(
    numbers.map(n.Number), texts.map(n.String), st.booleans().map(n.Boolean)
)
atoms: st.SearchStrategy[n.Expr] = st.one_of(
    literals,
    st.lists(literals, max_size=4).map(lambda items: n.SetLiteral(tuple(items))),
    st.builds(n.Param, st.sampled_from(list(n.Profile)), param_names),
    names.map(n.Name),
)


def _extend(inner: st.SearchStrategy[n.Expr]) -> st.SearchStrategy[n.Expr]:
    return st.one_of(
        st.builds(n.Or, inner, inner),
        st.builds(n.And, inner, inner),
        st.builds(n.Not, inner),
        st.builds(n.Compare, st.sampled_from(list(n.CompareOp)), inner, inner),
        st.builds(n.Member, inner, inner, st.booleans()),
    )


exprs = st.recursive(atoms, _extend, max_leaves=12)

simple_stmts: st.SearchStrategy[n.Stmt] = st.one_of(
    texts.map(n.Activate), texts.map(n.Cancel), names.map(n.Evaluate)
)


def _stmts(inner: st.SearchStrategy[n.Stmt]) -> st.SearchStrategy[n.Stmt]:
    return st.one_of(
        st.builds(n.If, exprs, inner, st.none() | inner),
        # a one-statement block is that statement, so blocks hold 0 or 2+ statements
        st.one_of(st.just(()), st.lists(inner, min_size=2, max_size=3).map(tuple)).map(n.Block),
    )


stmts = st.recursive(simple_stmts, _stmts, max_leaves=10)
items = st.one_of(
    st.builds(n.Definition, names, exprs),
    st.builds(n.Component, names, st.lists(stmts, max_size=3).map(tuple)),
)
programs = st.lists(items, max_size=4).map(lambda found: n.Program(tuple(found)))


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(programs)
def test_pretty_print_then_parse_gives_the_same_tree(program: n.Program) -> None:
    assert parse(pretty(program)) == program


def test_float_forms_round_trip() -> None:
    for value in (0.1, 1e-07, 1e16, -2.5, 1.7976931348623157e308, 5e-324):
        (definition,) = parse(pretty(n.Program((n.Definition("x", n.Number(value)),)))).items
        assert isinstance(definition, n.Definition)
        assert isinstance(definition.expr, n.Number)
        assert math.isclose(definition.expr.value, value) or definition.expr.value == value


TOKENS = [
    "def", "component", "if", "then", "else", "activate", "cancel", "evaluate",
    "or", "and", "not", "in", "true", "false", "params.user.age", "params.env.t",
    "params.x", "x", "C", "[", "]", "{", "}", "(", ")", ",", "=", "!=", "<", ">=",
    '"a"', '"', "1", "-2.5", "1e999", "//", "#", "\n", "\\", "$",
]  # fmt: skip


def _only_rules_errors(text: str) -> None:
    try:
        rules = rules_from_text(text)
    except RulesError as error:
        assert error.problems
        assert all(problem.line >= 1 and problem.column >= 1 for problem in error.problems)
        return
    for component in rules.components:
        # no parameter given: the component still decides, and names what it missed
        result = rules.evaluate(component, {})
        assert all(isinstance(name, str) for name in (*result.activate, *result.cancel))
        assert list(result.missing) == sorted(set(result.missing))


@settings(max_examples=200, deadline=None)
@given(st.text(max_size=80))
def test_arbitrary_text_raises_only_rules_error(text: str) -> None:
    _only_rules_errors(text)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.sampled_from(TOKENS), max_size=30).map(" ".join))
def test_token_soup_raises_only_rules_error(text: str) -> None:
    _only_rules_errors(text)


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(programs)
def test_generated_programs_verify_or_raise_rules_error(program: n.Program) -> None:
    _only_rules_errors(pretty(program))


def test_deep_nesting_is_a_rules_error_not_a_crash() -> None:
    parenthesized = "def x " + "(" * 3000 + "1" + ")" * 3000
    assert rules_from_text(parenthesized).components == frozenset()
    for text in (
        "def x " + "not " * 5000 + "true",
        "component C [" + "if params.user.a then " * 3000 + 'activate "a" ]',
    ):
        with pytest.raises(RulesError, match="rules nested too deeply"):
            rules_from_text(text)
