"""Syntax tree to Python closures, and :class:`RuleSet`, the compiled rules.

Each expression becomes a closure ``run -> value`` (``None`` is unknown), each statement
a closure ``run -> None`` that appends to the run's commands. Nothing is ever ``eval``-ed:
the closures only read the parameters the caller passes. Compile verified programs only
(:func:`dms.rules.loader.load_rules` does): the compiler assumes names resolve and
``evaluate`` has no cycles.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from dms.rules import nodes as n
from dms.rules.values import UNUSABLE, DmslSet, Value, normalize

Params = Mapping[str, Mapping[str, Any]]
_EMPTY: Mapping[str, Any] = {}
_PROFILE_INDEX = {n.Profile.USER: 0, n.Profile.ROBOT: 1, n.Profile.ENV: 2}


@dataclass(frozen=True, slots=True)
class RuleResult:
    """What a component decided: its commands in order, and the parameters it missed.

    ``missing`` names the ``params.*`` looked up without a value (``"user.age"``),
    sorted and unique.
    """

    activate: tuple[str, ...] = ()
    cancel: tuple[str, ...] = ()
    missing: tuple[str, ...] = ()
    activated_at: tuple[n.Pos, ...] = field(default=(), compare=False)
    """Where each ``activate`` that ran stands (file, line), in the order of ``activate``:
    what a decision's ``why`` names."""

    def to_json(self) -> dict[str, list[str]]:
        """The ``dms rules eval`` output object."""
        return {
            "activate": list(self.activate),
            "cancel": list(self.cancel),
            "missing": list(self.missing),
        }


class _Run:
    """The state of one evaluation: the three profiles and what was produced."""

    __slots__ = ("activate", "activated_at", "cancel", "missing", "profiles")

    def __init__(self, params: Params) -> None:
        self.profiles: tuple[Mapping[str, Any], ...] = (
            _profile(params, "user"),
            _profile(params, "robot"),
            _profile(params, "env"),
        )
        self.missing: list[str] = []
        self.activate: list[str] = []
        self.activated_at: list[n.Pos] = []
        self.cancel: list[str] = []


def _profile(params: Params, name: str) -> Mapping[str, Any]:
    profile = params.get(name) if isinstance(params, Mapping) else None
    return profile if isinstance(profile, Mapping) else _EMPTY


ExprFn = Callable[[_Run], Value]
StmtFn = Callable[[_Run], None]


def uses_params(expr: n.Expr, definitions: Mapping[str, n.Definition]) -> bool:
    """Whether ``expr`` reads a parameter, directly or through ``def`` names."""
    seen: set[str] = set()
    stack: list[n.Expr] = [expr]
    while stack:
        node = stack.pop()
        if isinstance(node, n.Param):
            return True
        if isinstance(node, n.Name):
            definition = definitions.get(node.name)
            if definition is not None and node.name not in seen:
                seen.add(node.name)
                stack.append(definition.expr)
        elif isinstance(node, n.Compare | n.And | n.Or):
            stack.extend((node.left, node.right))
        elif isinstance(node, n.Member):
            stack.extend((node.element, node.collection))
        elif isinstance(node, n.Not):
            stack.append(node.operand)
    return False


def _is_number(value: object) -> bool:
    kind = type(value)
    return kind is int or kind is float


def equal(a: Value, b: Value) -> bool | None:
    """``a = b``: unknown when either is unknown or they are of different kinds."""
    if a is None or b is None:
        return None
    ta, tb = type(a), type(b)
    if ta is tb or (_is_number(a) and _is_number(b)):
        return a == b
    return None


_ORDER: dict[n.CompareOp, Callable[[Any, Any], bool]] = {
    n.CompareOp.LT: lambda a, b: a < b,
    n.CompareOp.LE: lambda a, b: a <= b,
    n.CompareOp.GT: lambda a, b: a > b,
    n.CompareOp.GE: lambda a, b: a >= b,
}


class _Compiler:
    """Compiles the expressions and statements of a set of programs."""

    def __init__(
        self,
        definitions: Mapping[str, n.Definition],
        bodies: dict[str, StmtFn],
    ) -> None:
        self.definitions = definitions
        self.bodies = bodies
        self.named: dict[str, ExprFn] = {}

    # -------------------------------------------------------------- expressions

    def expr(self, expr: n.Expr) -> ExprFn:
        if not isinstance(expr, n.Param) and not uses_params(expr, self.definitions):
            value = self._expr(expr)(_Run(_EMPTY))  # constant: fold it once
            return lambda run: value
        return self._expr(expr)

    def _expr(self, expr: n.Expr) -> ExprFn:
        if isinstance(expr, n.Number | n.String | n.Boolean):
            literal = expr.value
            return lambda run: literal
        if isinstance(expr, n.SetLiteral):
            made = DmslSet.of(item.value for item in expr.items)
            return lambda run: made
        if isinstance(expr, n.Param):
            return _param(_PROFILE_INDEX[expr.profile], expr.name, expr.key)
        if isinstance(expr, n.Name):
            return self._name(expr.name)
        if isinstance(expr, n.Not):
            return _not(self.expr(expr.operand))
        if isinstance(expr, n.And):
            return _and(self.expr(expr.left), self.expr(expr.right))
        if isinstance(expr, n.Or):
            return _or(self.expr(expr.left), self.expr(expr.right))
        if isinstance(expr, n.Compare):
            return self._compare(expr)
        return self._member(expr)

    def _name(self, name: str) -> ExprFn:
        compiled = self.named.get(name)
        if compiled is None:
            compiled = self.expr(self.definitions[name].expr)
            self.named[name] = compiled
        return compiled

    def _compare(self, expr: n.Compare) -> ExprFn:
        left = self.expr(expr.left)
        if expr.op in (n.CompareOp.EQ, n.CompareOp.NE):
            right = self.expr(expr.right)
            if expr.op is n.CompareOp.EQ:
                return lambda run: equal(left(run), right(run))
            return _not(lambda run: equal(left(run), right(run)))
        order = _ORDER[expr.op]
        if isinstance(expr.right, n.Number):
            bound = expr.right.value

            def against_literal(run: _Run) -> bool | None:
                value = left(run)
                kind = type(value)
                if kind is int or kind is float:
                    return order(value, bound)
                return None

            return against_literal
        right = self.expr(expr.right)

        def ordered(run: _Run) -> bool | None:
            a, b = left(run), right(run)
            if _is_number(a) and _is_number(b):
                return order(a, b)
            return None

        return ordered

    def _member(self, expr: n.Member) -> ExprFn:
        element = self.expr(expr.element)
        collection = self.expr(expr.collection)
        negated = expr.negated
        if not uses_params(expr.collection, self.definitions):
            fixed = collection(_Run(_EMPTY))
            if isinstance(fixed, DmslSet):
                return _member_of(element, fixed, negated)

        def member(run: _Run) -> bool | None:
            value = element(run)
            found = collection(run)
            if value is None or not isinstance(found, DmslSet):
                return None
            inside = found.contains(value)
            if inside is None:
                return None
            return not inside if negated else inside

        return member

    # --------------------------------------------------------------- statements

    def stmt(self, stmt: n.Stmt) -> StmtFn:
        if isinstance(stmt, n.Activate):
            name, pos = stmt.name, stmt.pos

            def activate(run: _Run) -> None:
                run.activate.append(name)
                run.activated_at.append(pos)

            return activate
        if isinstance(stmt, n.Cancel):
            cancelled = stmt.name
            return lambda run: run.cancel.append(cancelled)
        if isinstance(stmt, n.Evaluate):
            bodies, target = self.bodies, stmt.component
            return lambda run: bodies[target](run)
        if isinstance(stmt, n.Block):
            return self.block(stmt.body)
        cond = self.expr(stmt.cond)
        then = self.stmt(stmt.then)
        if stmt.else_ is None:

            def if_then(run: _Run) -> None:
                if cond(run) is True:
                    then(run)

            return if_then
        else_ = self.stmt(stmt.else_)

        def if_else(run: _Run) -> None:
            if cond(run) is True:
                then(run)
            else:
                else_(run)

        return if_else

    def block(self, body: tuple[n.Stmt, ...]) -> StmtFn:
        steps = tuple(self.stmt(stmt) for stmt in body)
        if len(steps) == 1:
            return steps[0]

        def run_all(run: _Run) -> None:
            for step in steps:
                step(run)

        return run_all


def _param(index: int, name: str, key: str) -> ExprFn:
    def get(run: _Run) -> Value:
        value = run.profiles[index].get(name)
        kind = type(value)
        if kind is int or kind is float or kind is str or kind is bool:
            return value
        if value is None:
            run.missing.append(key)
            return None
        usable = normalize(value)
        return None if usable is UNUSABLE else usable  # type: ignore[return-value]

    return get


def _not(operand: ExprFn) -> ExprFn:
    def not_(run: _Run) -> bool | None:
        value = operand(run)
        if value is True:
            return False
        if value is False:
            return True
        return None

    return not_


def _and(left: ExprFn, right: ExprFn) -> ExprFn:
    def and_(run: _Run) -> bool | None:
        a = left(run)
        if a is False:
            return False
        b = right(run)
        if b is False:
            return False
        return True if a is True and b is True else None

    return and_


def _or(left: ExprFn, right: ExprFn) -> ExprFn:
    def or_(run: _Run) -> bool | None:
        a = left(run)
        if a is True:
            return True
        b = right(run)
        if b is True:
            return True
        return False if a is False and b is False else None

    return or_


def _member_of(element: ExprFn, fixed: DmslSet, negated: bool) -> ExprFn:
    numbers, strings, booleans = fixed.numbers, fixed.strings, fixed.booleans

    def member(run: _Run) -> bool | None:
        value = element(run)
        kind = type(value)
        if kind is int or kind is float:
            inside = value in numbers
        elif kind is str:
            inside = value in strings
        elif kind is bool:
            inside = value in booleans
        else:
            return None
        return not inside if negated else inside

    return member


class RuleSet:
    """Compiled, verified rules: evaluate a component against ``params``.

    Immutable once built; share it between threads freely.
    """

    def __init__(self, programs: tuple[n.Program, ...]) -> None:
        self.programs = programs
        self.definitions: dict[str, n.Definition] = {}
        self.component_nodes: dict[str, n.Component] = {}
        for program in programs:
            for item in program.items:
                if isinstance(item, n.Definition):
                    self.definitions.setdefault(item.name, item)
                else:
                    self.component_nodes.setdefault(item.name, item)
        self._bodies: dict[str, StmtFn] = {}
        compiler = _Compiler(self.definitions, self._bodies)
        for name, component in self.component_nodes.items():
            self._bodies[name] = compiler.block(component.body)
        self.components: frozenset[str] = frozenset(self.component_nodes)

    def defines(self, component: str) -> bool:
        """Whether a rules file has a block for ``component``."""
        return component in self._bodies

    def evaluate(self, component: str, params: Params) -> RuleResult:
        """Run ``component``'s block against ``params`` (``{"user": {...}, ...}``).

        Raises:
            KeyError: no rules file defines ``component``.
        """
        body = self._bodies[component]
        run = _Run(params)
        body(run)
        missing = run.missing
        return RuleResult(
            tuple(run.activate),
            tuple(run.cancel),
            tuple(sorted(set(missing))) if missing else (),
            tuple(run.activated_at),
        )
