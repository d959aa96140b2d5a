"""Syntax tree back to DMSL text: ``parse(pretty(program)) == program``.

Parentheses appear only where precedence needs them; a ``then`` branch that ends in an
``if`` without ``else`` is bracketed when an ``else`` follows, so the ``else`` keeps
its ``if``.
"""

from __future__ import annotations

from dms.rules import nodes as n

_OR, _AND, _NOT, _CMP, _ATOM = 1, 2, 3, 4, 5
_ESCAPE = {"\\": "\\\\", '"': '\\"', "\n": "\\n", "\t": "\\t", "\r": "\\r"}
INDENT = "    "


def quote(text: str) -> str:
    """A DMSL string literal for ``text``."""
    return '"' + "".join(_ESCAPE.get(char, char) for char in text) + '"'


def _number(value: int | float) -> str:
    return repr(value) if isinstance(value, float) else str(value)


def expr_text(expr: n.Expr, context: int = _OR) -> str:
    """``expr`` as text, parenthesized when its precedence is below ``context``."""
    level, text = _expr(expr)
    return f"({text})" if level < context else text


def _expr(expr: n.Expr) -> tuple[int, str]:
    if isinstance(expr, n.Number):
        return _ATOM, _number(expr.value)
    if isinstance(expr, n.String):
        return _ATOM, quote(expr.value)
    if isinstance(expr, n.Boolean):
        return _ATOM, "true" if expr.value else "false"
    if isinstance(expr, n.SetLiteral):
        return _ATOM, "{" + ", ".join(expr_text(item) for item in expr.items) + "}"
    if isinstance(expr, n.Param):
        return _ATOM, f"params.{expr.profile.value}.{expr.name}"
    if isinstance(expr, n.Name):
        return _ATOM, expr.name
    if isinstance(expr, n.Or):
        return _OR, f"{expr_text(expr.left, _OR)} or {expr_text(expr.right, _AND)}"
    if isinstance(expr, n.And):
        return _AND, f"{expr_text(expr.left, _AND)} and {expr_text(expr.right, _NOT)}"
    if isinstance(expr, n.Not):
        return _NOT, f"not {expr_text(expr.operand, _NOT)}"
    if isinstance(expr, n.Compare):
        left, right = expr_text(expr.left, _ATOM), expr_text(expr.right, _ATOM)
        return _CMP, f"{left} {expr.op.value} {right}"
    word = "not in" if expr.negated else "in"
    element, collection = expr_text(expr.element, _ATOM), expr_text(expr.collection, _ATOM)
    return _CMP, f"{element} {word} {collection}"


def _ends_open(stmt: n.Stmt) -> bool:
    """Whether an ``else`` written after ``stmt`` would attach to an ``if`` inside it."""
    while isinstance(stmt, n.If):
        if stmt.else_ is None:
            return True
        stmt = stmt.else_
    return False


def stmt_lines(stmt: n.Stmt, depth: int = 0) -> list[str]:
    """``stmt`` as indented lines."""
    pad = INDENT * depth
    if isinstance(stmt, n.Activate):
        return [f"{pad}activate {quote(stmt.name)}"]
    if isinstance(stmt, n.Cancel):
        return [f"{pad}cancel {quote(stmt.name)}"]
    if isinstance(stmt, n.Evaluate):
        return [f"{pad}evaluate {stmt.component}"]
    if isinstance(stmt, n.Block):
        inner = [line for child in stmt.body for line in stmt_lines(child, depth + 1)]
        return [f"{pad}[", *inner, f"{pad}]"]
    lines = [f"{pad}if {expr_text(stmt.cond)} then"]
    if stmt.else_ is not None and _ends_open(stmt.then):
        lines += [f"{pad}[", *stmt_lines(stmt.then, depth + 1), f"{pad}]"]
    else:
        lines += stmt_lines(stmt.then, depth + 1)
    if stmt.else_ is not None:
        if isinstance(stmt.else_, n.If):
            chained = stmt_lines(stmt.else_, depth)
            lines += [f"{pad}else {chained[0].lstrip()}", *chained[1:]]
        else:
            lines += [f"{pad}else", *stmt_lines(stmt.else_, depth + 1)]
    return lines


def pretty(program: n.Program) -> str:
    """The whole program as DMSL text."""
    out: list[str] = []
    for item in program.items:
        if isinstance(item, n.Definition):
            out.append(f"def {item.name} {expr_text(item.expr)}")
        else:
            out.append(f"component {item.name} [")
            out += [line for stmt in item.body for line in stmt_lines(stmt, 1)]
            out.append("]")
    return "\n".join(out) + "\n"
