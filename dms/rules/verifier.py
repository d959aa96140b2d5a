"""Static checks of parsed DMSL programs (docs/dmsl.md, "The verifier").

:func:`verify` takes every program that is loaded together (definitions and components
share one namespace across files) and returns every problem found: duplicates,
unknown names and components, ``def`` and ``evaluate`` cycles, type errors, unknown
parameters (with a schema), rules too big to check (:mod:`.budget`), constant
conditions, branches that can never run and components that never activate anything.
:func:`outcome_problems` checks activations against the outcomes a state machine state
declares.
"""

from __future__ import annotations

import difflib
from collections.abc import Callable, Collection, Iterable, Iterator, Mapping
from dataclasses import dataclass, field

from dms.rules import nodes as n
from dms.rules.budget import oversized
from dms.rules.compiler import _Compiler, _Run, uses_params
from dms.rules.problems import Problem
from dms.rules.schema import ParameterSchema
from dms.rules.values import Kind

Truth = frozenset[bool | None]
ALL: Truth = frozenset({True, False, None})
ONLY_TRUE: Truth = frozenset({True})
ONLY_FALSE: Truth = frozenset({False})
_ARTICLE = {Kind.NUMBER: "a number", Kind.STRING: "a string", Kind.BOOLEAN: "true or false"}
_ARTICLE[Kind.SET] = "a set"


def _kind_text(kind: Kind) -> str:
    return _ARTICLE[kind]


def _did_you_mean(name: str, choices: Iterable[str]) -> str:
    close = difflib.get_close_matches(name, list(choices), n=1)
    return f"; did you mean '{close[0]}'?" if close else ""


def _children(expr: n.Expr) -> tuple[n.Expr, ...]:
    if isinstance(expr, n.Compare | n.And | n.Or):
        return (expr.left, expr.right)
    if isinstance(expr, n.Member):
        return (expr.element, expr.collection)
    if isinstance(expr, n.Not):
        return (expr.operand,)
    return ()


def walk_expr(expr: n.Expr) -> Iterator[n.Expr]:
    """Every node of ``expr`` (not following names)."""
    stack = [expr]
    while stack:
        node = stack.pop()
        yield node
        stack.extend(_children(node))


def walk_stmts(body: Iterable[n.Stmt]) -> Iterator[n.Stmt]:
    """Every statement of ``body``, nested ones included."""
    stack = list(body)
    while stack:
        stmt = stack.pop()
        yield stmt
        if isinstance(stmt, n.Block):
            stack.extend(stmt.body)
        elif isinstance(stmt, n.If):
            stack.append(stmt.then)
            if stmt.else_ is not None:
                stack.append(stmt.else_)


def _neg(value: bool | None) -> bool | None:
    return None if value is None else not value


def _and(a: bool | None, b: bool | None) -> bool | None:
    if a is False or b is False:
        return False
    return True if a is True and b is True else None


def _or(a: bool | None, b: bool | None) -> bool | None:
    if a is True or b is True:
        return True
    return False if a is False and b is False else None


def _combine(op: Callable[[bool | None, bool | None], bool | None], a: Truth, b: Truth) -> Truth:
    return frozenset(op(x, y) for x in a for y in b)


@dataclass
class _Checker:
    programs: tuple[n.Program, ...]
    schema: ParameterSchema | None
    sources: Mapping[str, list[str]]
    problems: list[Problem] = field(default_factory=list)
    definitions: dict[str, n.Definition] = field(default_factory=dict)
    components: dict[str, n.Component] = field(default_factory=dict)
    broken_names: set[str] = field(default_factory=set)
    kinds: dict[str, Kind | None] = field(default_factory=dict)
    params_read: dict[int, bool] = field(default_factory=dict)

    def report(self, pos: n.Pos, message: str) -> None:
        self.problems.append(Problem.at(pos, message, self.sources.get(pos.file)))

    # ---------------------------------------------------------------- namespace

    def collect(self) -> None:
        for program in self.programs:
            for item in program.items:
                table: dict[str, n.Definition] | dict[str, n.Component]
                if isinstance(item, n.Definition):
                    table, what = self.definitions, "definition"
                else:
                    table, what = self.components, "component"
                first = table.get(item.name)
                if first is not None:
                    where = f"{first.pos.file}:{first.pos.line}:{first.pos.column}"
                    self.report(item.pos, f"duplicate {what} '{item.name}' (first at {where})")
                else:
                    table[item.name] = item  # type: ignore[assignment]

    def all_exprs(self) -> Iterator[n.Expr]:
        for definition in self.definitions.values():
            yield definition.expr
        for component in self.components.values():
            for stmt in walk_stmts(component.body):
                if isinstance(stmt, n.If):
                    yield stmt.cond

    def check_names(self) -> None:
        for expr in self.all_exprs():
            for node in walk_expr(expr):
                if isinstance(node, n.Name) and node.name not in self.definitions:
                    self.broken_names.add(node.name)
                    if node.name in self.components:
                        hint = f"; '{node.name}' is a component (use evaluate)"
                    else:
                        hint = _did_you_mean(node.name, self.definitions)
                    self.report(node.pos, f"unknown name '{node.name}'{hint}")
                elif isinstance(node, n.Param) and self.schema is not None:
                    known = self.schema.profile(node.profile.value)
                    if node.name not in known:
                        hint = _did_you_mean(node.name, known)
                        self.report(node.pos, f"unknown parameter params.{node.key}{hint}")
        for component in self.components.values():
            for stmt in walk_stmts(component.body):
                if isinstance(stmt, n.Evaluate) and stmt.component not in self.components:
                    if stmt.component in self.definitions:
                        hint = f"; '{stmt.component}' is a def, not a component"
                    else:
                        hint = _did_you_mean(stmt.component, self.components)
                    self.report(stmt.pos, f"evaluate of unknown component '{stmt.component}'{hint}")

    def check_cycles(self) -> None:
        def refs(name: str) -> list[tuple[str, n.Pos]]:
            return [
                (node.name, node.pos)
                for node in walk_expr(self.definitions[name].expr)
                if isinstance(node, n.Name) and node.name in self.definitions
            ]

        def calls(name: str) -> list[tuple[str, n.Pos]]:
            return [
                (stmt.component, stmt.pos)
                for stmt in walk_stmts(self.components[name].body)
                if isinstance(stmt, n.Evaluate) and stmt.component in self.components
            ]

        self.broken_names |= self._cycles(self.definitions, refs, "definition cycle")
        self._cycles(self.components, calls, "evaluate cycle")

    def _cycles(
        self,
        names: Mapping[str, object],
        edges: Callable[[str], list[tuple[str, n.Pos]]],
        what: str,
    ) -> set[str]:
        """Depth-first search; reports each back edge; returns the names on cycles."""
        state: dict[str, int] = {}  # 1 on the stack, 2 done
        on_cycles: set[str] = set()
        for root in names:
            if root in state:
                continue
            path: list[str] = [root]
            state[root] = 1
            stack: list[Iterator[tuple[str, n.Pos]]] = [iter(edges(root))]
            while stack:
                step = next(stack[-1], None)
                if step is None:
                    stack.pop()
                    state[path.pop()] = 2
                    continue
                target, pos = step
                if state.get(target) == 1:
                    cycle = [*path[path.index(target) :], target]
                    on_cycles.update(cycle)
                    self.report(pos, f"{what}: {' -> '.join(cycle)}")
                elif target not in state:
                    state[target] = 1
                    path.append(target)
                    stack.append(iter(edges(target)))
        return on_cycles

    # -------------------------------------------------------------------- types

    def name_kind(self, name: str) -> Kind | None:
        if name in self.broken_names or name not in self.definitions:
            return None
        if name not in self.kinds:
            self.kinds[name] = None
            self.kinds[name] = self.kind(self.definitions[name].expr, report=False)
        return self.kinds[name]

    def set_elements(self, expr: n.Expr) -> frozenset[Kind] | None:
        """The element kinds of a set known before the rules run."""
        seen: set[str] = set()
        while isinstance(expr, n.Name):
            if expr.name in seen or expr.name not in self.definitions:
                return None
            seen.add(expr.name)
            expr = self.definitions[expr.name].expr
        if not isinstance(expr, n.SetLiteral) or not expr.items:
            return None
        return frozenset(
            Kind.NUMBER
            if isinstance(item, n.Number)
            else Kind.STRING
            if isinstance(item, n.String)
            else Kind.BOOLEAN
            for item in expr.items
        )

    def kind(self, expr: n.Expr, report: bool = True) -> Kind | None:
        """The kind of ``expr`` (``None``: not known before the rules run)."""
        say = self.report if report else (lambda pos, message: None)
        if isinstance(expr, n.Number):
            return Kind.NUMBER
        if isinstance(expr, n.String):
            return Kind.STRING
        if isinstance(expr, n.Boolean):
            return Kind.BOOLEAN
        if isinstance(expr, n.SetLiteral):
            return Kind.SET
        if isinstance(expr, n.Param):
            if self.schema is None:
                return None
            declared = self.schema.profile(expr.profile.value).get(expr.name)
            return Kind(declared) if declared is not None else None
        if isinstance(expr, n.Name):
            return self.name_kind(expr.name)
        if isinstance(expr, n.Not | n.And | n.Or):
            word = "not" if isinstance(expr, n.Not) else "and" if isinstance(expr, n.And) else "or"
            for operand in _children(expr):
                found = self.kind(operand, report)
                if found not in (None, Kind.BOOLEAN):
                    say(
                        operand.pos,
                        f"type error: '{word}' needs true or false, got {_kind_text(found)}",
                    )
            return Kind.BOOLEAN
        if isinstance(expr, n.Compare):
            left, right = self.kind(expr.left, report), self.kind(expr.right, report)
            op = expr.op.value
            if expr.op in (n.CompareOp.EQ, n.CompareOp.NE):
                if left is not None and right is not None and left is not right:
                    say(
                        expr.pos,
                        f"type error: '{op}' compares {_kind_text(left)} with {_kind_text(right)}",
                    )
            else:
                for side, found in ((expr.left, left), (expr.right, right)):
                    if found not in (None, Kind.NUMBER):
                        say(side.pos, f"type error: '{op}' needs numbers, got {_kind_text(found)}")
            return Kind.BOOLEAN
        assert isinstance(expr, n.Member)
        word = "not in" if expr.negated else "in"
        element, collection = self.kind(expr.element, report), self.kind(expr.collection, report)
        if collection not in (None, Kind.SET):
            say(
                expr.collection.pos,
                f"type error: '{word}' needs a set on its right, got {_kind_text(collection)}",
            )
        if element is Kind.SET:
            say(expr.element.pos, f"type error: '{word}' needs a value on its left, got a set")
        elements = self.set_elements(expr.collection)
        if element is not None and element is not Kind.SET and elements and element not in elements:
            kinds = " and ".join(sorted(f"{kind.value}s" for kind in elements))
            say(expr.pos, f"type error: a {element.value} is never in a set of {kinds}")
        return Kind.BOOLEAN

    def check_size(self) -> None:
        """Refuse what is too big to check or run once ``def``s are written out."""
        conditions = sorted(
            (
                stmt.cond
                for component in self.components.values()
                for stmt in walk_stmts(component.body)
                if isinstance(stmt, n.If)
            ),
            key=lambda cond: (cond.pos.file, cond.pos.line, cond.pos.column),
        )
        for pos, message in oversized(self.definitions, conditions, self.broken_names):
            self.report(pos, message)

    def check_types(self) -> None:
        for definition in self.definitions.values():
            if definition.name not in self.broken_names:
                self.kind(definition.expr)
        for component in self.components.values():
            for stmt in walk_stmts(component.body):
                if isinstance(stmt, n.If):
                    found = self.kind(stmt.cond)
                    if found not in (None, Kind.BOOLEAN):
                        self.report(
                            stmt.cond.pos,
                            f"type error: condition must be true or false, got {_kind_text(found)}",
                        )

    # --------------------------------------------------------------------- flow

    def flow(self) -> None:
        self.compiler = _Compiler(self.definitions, {})
        self.activates: dict[str, bool] = {}
        for name, component in self.components.items():
            if not self._component_activates(name, report=True):
                self.report(component.pos, f"component '{name}' never activates anything")

    def _component_activates(self, name: str, report: bool) -> bool:
        if not report and name in self.activates:
            return self.activates[name]
        self.activates.setdefault(name, False)  # an evaluate cycle adds nothing
        found = False
        for stmt in self.components[name].body:
            found = self._walk(stmt, {}, report) or found
        self.activates[name] = found
        return found

    def reads_params(self, expr: n.Expr) -> bool:
        """:func:`uses_params`, once per node: :meth:`truth` asks at every node."""
        key = id(expr)  # the nodes live as long as the checker's programs
        if key not in self.params_read:
            self.params_read[key] = uses_params(expr, self.definitions)
        return self.params_read[key]

    def truth(self, expr: n.Expr, assumed: Mapping[n.Expr, Truth]) -> Truth:
        """The truth values ``expr`` can take on this path (Kleene, ``None`` unknown)."""
        if not self.reads_params(expr):
            value = self.compiler.expr(expr)(_Run({}))
            return frozenset({value if isinstance(value, bool) else None})
        base = assumed.get(expr, ALL)
        found: Truth
        if isinstance(expr, n.Name):
            found = self.truth(self.definitions[expr.name].expr, assumed)
        elif isinstance(expr, n.Not):
            found = frozenset(_neg(value) for value in self.truth(expr.operand, assumed))
        elif isinstance(expr, n.And):
            found = _combine(_and, self.truth(expr.left, assumed), self.truth(expr.right, assumed))
        elif isinstance(expr, n.Or):
            found = _combine(_or, self.truth(expr.left, assumed), self.truth(expr.right, assumed))
        else:
            found = ALL
        return base & found

    def assume(self, expr: n.Expr, values: Truth, assumed: dict[n.Expr, Truth]) -> None:
        """Record that ``expr`` takes one of ``values`` on this path, and what follows."""
        assumed[expr] = assumed.get(expr, ALL) & values
        if isinstance(expr, n.Name):
            self.assume(self.definitions[expr.name].expr, values, assumed)
        elif isinstance(expr, n.Not):
            self.assume(expr.operand, frozenset(_neg(value) for value in values), assumed)
        elif isinstance(expr, n.And) and False not in values:
            # true or unknown: neither side is false
            for side in (expr.left, expr.right):
                self.assume(side, values | ONLY_TRUE, assumed)
        elif isinstance(expr, n.Or) and True not in values:
            # false or unknown: neither side is true
            for side in (expr.left, expr.right):
                self.assume(side, values | ONLY_FALSE, assumed)

    def _walk(self, stmt: n.Stmt, assumed: dict[n.Expr, Truth], report: bool) -> bool:
        """Whether ``stmt`` can activate something; reports dead code when ``report``."""
        if isinstance(stmt, n.Activate):
            return True
        if isinstance(stmt, n.Cancel):
            return False
        if isinstance(stmt, n.Evaluate):
            return self._component_activates(stmt.component, report=False)
        if isinstance(stmt, n.Block):
            found = False
            for inner in stmt.body:
                found = self._walk(inner, assumed, report) or found
            return found
        possible = self.truth(stmt.cond, assumed)
        if report and (possible == ONLY_TRUE or True not in possible):
            alone = self.truth(stmt.cond, {})
            always = "always true" if possible == ONLY_TRUE else "never true"
            here = "" if alone == possible else " here (the enclosing conditions decide it)"
            self.report(stmt.cond.pos, f"condition is {always}{here}")
        found = False
        if True in possible:
            then_assumed = dict(assumed)
            self.assume(stmt.cond, ONLY_TRUE, then_assumed)
            found = self._walk(stmt.then, then_assumed, report)
        elif report:
            self.report(stmt.then.pos, "this branch can never run")
        if stmt.else_ is not None:
            if possible != ONLY_TRUE:
                else_assumed = dict(assumed)
                self.assume(stmt.cond, possible - ONLY_TRUE, else_assumed)
                found = self._walk(stmt.else_, else_assumed, report) or found
            elif report:
                self.report(stmt.else_.pos, "this branch can never run")
        return found


def verify(
    programs: Iterable[n.Program],
    schema: ParameterSchema | None = None,
    sources: Mapping[str, list[str]] | None = None,
) -> list[Problem]:
    """Every problem of ``programs`` checked together; ``sources`` gives excerpt lines."""
    checker = _Checker(tuple(programs), schema, sources or {})
    try:
        checker.collect()
        checker.check_names()
        checker.check_cycles()
        checker.check_size()
        checker.check_types()
        if not checker.problems:  # flow analysis runs the constant parts: sound code only
            checker.flow()
    except RecursionError:
        first = next((p for p in checker.programs if p.items), None)
        pos = first.items[0].pos if first is not None else n.NOWHERE
        checker.report(pos, "rules nested too deeply")
    return sorted(checker.problems, key=lambda p: (p.file, p.line, p.column, p.message))


def outcome_problems(
    components: Mapping[str, n.Component], component: str, outcomes: Collection[str]
) -> list[Problem]:
    """Activations reachable from ``component`` that are not among ``outcomes``."""
    problems: list[Problem] = []
    pending, seen = [component], set()
    allowed = ", ".join(f'"{outcome}"' for outcome in sorted(outcomes)) or "none"
    while pending:
        name = pending.pop()
        if name in seen or name not in components:
            continue
        seen.add(name)
        for stmt in walk_stmts(components[name].body):
            if isinstance(stmt, n.Evaluate):
                pending.append(stmt.component)
            elif isinstance(stmt, n.Activate) and stmt.name not in outcomes:
                problems.append(
                    Problem.at(
                        stmt.pos,
                        f'activation "{stmt.name}" of {component} is not an outcome '
                        f"of the state (outcomes: {allowed})",
                    )
                )
    return sorted(problems, key=lambda p: (p.file, p.line, p.column))


def activation_warnings(programs: Iterable[n.Program]) -> list[Problem]:
    """Components that may activate nothing: some path through them activates nothing.

    A warning, not an error: the caller's built-in logic decides on such a path, as the
    DMSL paper's ``ObstacleDetected`` intends. Run it on rules that :func:`verify` accepts
    (no cycles, no dead branches), so that every branch can run. The warning points at
    the first statement on such a path that may activate nothing, typically an ``if``
    without an ``else``.
    """
    components = {
        item.name: item
        for program in programs
        for item in program.items
        if isinstance(item, n.Component)
    }
    memo: dict[str, n.Pos | None] = {}

    def component_gap(name: str) -> n.Pos | None:
        """Where ``name`` may activate nothing, or ``None`` when it always activates."""
        component = components[name]
        if name not in memo:
            memo[name] = component.pos  # inside an evaluate cycle: nothing by itself
            memo[name] = body_gap(component.body, component.pos)
        return memo[name]

    def body_gap(body: Iterable[n.Stmt], empty: n.Pos) -> n.Pos | None:
        """A sequence activates something when one of its statements always does."""
        gaps = []
        for stmt in body:
            gap = stmt_gap(stmt)
            if gap is None:
                return None
            gaps.append(gap)
        return gaps[0] if gaps else empty

    def stmt_gap(stmt: n.Stmt) -> n.Pos | None:
        if isinstance(stmt, n.Activate):
            return None
        if isinstance(stmt, n.Cancel):
            return stmt.pos
        if isinstance(stmt, n.Evaluate):
            return component_gap(stmt.component) if stmt.component in components else stmt.pos
        if isinstance(stmt, n.Block):
            return body_gap(stmt.body, stmt.pos)
        if stmt.else_ is None:
            return stmt.pos
        then_gap = stmt_gap(stmt.then)
        return then_gap if then_gap is not None else stmt_gap(stmt.else_)

    warnings = []
    for name in components:
        gap = component_gap(name)
        if gap is not None:
            warnings.append(
                Problem.at(
                    gap,
                    f"warning: component '{name}' may activate nothing on a path through "
                    "here (the caller's built-in logic decides then)",
                )
            )
    return sorted(warnings, key=lambda p: (p.file, p.line, p.column, p.message))
