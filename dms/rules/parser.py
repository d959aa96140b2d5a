"""Text to syntax tree: the lark grammar in ``dmsl.lark`` and a transformer to :mod:`nodes`.

:func:`parse` raises :class:`RulesError` and nothing else, whatever the text.
"""

from __future__ import annotations

import math
from functools import cache
from typing import Any

from lark import Lark, Token, Transformer, v_args
from lark.exceptions import UnexpectedCharacters, UnexpectedInput, UnexpectedToken, VisitError

from dms.rules import nodes as n
from dms.rules.problems import Problem, RulesError

_TOO_DEEP = "rules nested too deeply"
_ESCAPES = {'"': '"', "\\": "\\", "n": "\n", "t": "\t", "r": "\r"}
_PROFILES = {profile.value: profile for profile in n.Profile}
KEYWORDS = frozenset(
    {"def", "component", "if", "then", "else", "activate", "cancel", "evaluate"}
    | {"or", "and", "not", "in", "true", "false"}
)

_TOKEN_NAMES = {
    "NAME": "a name",
    "STRING": "a string",
    "NUMBER": "a number",
    "PARAM": "params.<profile>.<name>",
    "COMP_OP": "a comparison",
    "LSQB": "'['",
    "RSQB": "']'",
    "LBRACE": "'{'",
    "RBRACE": "'}'",
    "LPAR": "'('",
    "RPAR": "')'",
    "COMMA": "','",
    "$END": "end of file",
}


@cache
def _parser() -> Lark:
    return Lark.open(
        "dmsl.lark", rel_to=__file__, parser="lalr", lexer="basic", propagate_positions=True
    )


class _Invalid(Exception):
    """A well-formed token with a bad value (unknown profile, bad escape, huge number)."""

    def __init__(self, line: int, column: int, message: str) -> None:
        super().__init__(message)
        self.line = line
        self.column = column
        self.message = message


def _unquote(token: Token) -> str:
    body = str(token)[1:-1]
    out: list[str] = []
    index = 0
    while index < len(body):
        char = body[index]
        if char == "\\":
            escaped = body[index + 1]
            if escaped not in _ESCAPES:
                raise _Invalid(
                    token.line or 1,
                    (token.column or 1) + index + 1,
                    f"unknown escape '\\{escaped}' in string (use \\\" \\\\ \\n \\t \\r)",
                )
            out.append(_ESCAPES[escaped])
            index += 2
        else:
            out.append(char)
            index += 1
    return "".join(out)


@v_args(meta=True)
class _Build(Transformer[Token, n.Program]):
    """Builds the syntax tree; ``file`` goes into every position."""

    def __init__(self, file: str) -> None:
        super().__init__()
        self.file = file

    def _pos(self, meta: Any) -> n.Pos:
        if getattr(meta, "empty", True):
            return n.Pos(self.file, 1, 1)
        return n.Pos(self.file, meta.line, meta.column)

    def start(self, meta: Any, items: list[Any]) -> n.Program:
        return n.Program(tuple(items))

    def definition(self, meta: Any, children: list[Any]) -> n.Definition:
        name, expr = children
        return n.Definition(str(name), expr, self._pos(meta))

    def component(self, meta: Any, children: list[Any]) -> n.Component:
        return n.Component(str(children[0]), tuple(children[1:]), self._pos(meta))

    def if_else(self, meta: Any, children: list[Any]) -> n.If:
        cond, then, else_ = children
        return n.If(cond, then, else_, self._pos(meta))

    def if_then(self, meta: Any, children: list[Any]) -> n.If:
        cond, then = children
        return n.If(cond, then, None, self._pos(meta))

    def activate(self, meta: Any, children: list[Any]) -> n.Activate:
        return n.Activate(_unquote(children[0]), self._pos(meta))

    def cancel(self, meta: Any, children: list[Any]) -> n.Cancel:
        return n.Cancel(_unquote(children[0]), self._pos(meta))

    def evaluate(self, meta: Any, children: list[Any]) -> n.Evaluate:
        return n.Evaluate(str(children[0]), self._pos(meta))

    def block(self, meta: Any, children: list[Any]) -> n.Stmt:
        # `[ s ]` means the same as `s`; one shape for both keeps the tree canonical.
        if len(children) == 1:
            only: n.Stmt = children[0]
            return only
        return n.Block(tuple(children), self._pos(meta))

    def or_(self, meta: Any, children: list[Any]) -> n.Or:
        return n.Or(children[0], children[1], self._pos(meta))

    def and_(self, meta: Any, children: list[Any]) -> n.And:
        return n.And(children[0], children[1], self._pos(meta))

    def not_(self, meta: Any, children: list[Any]) -> n.Not:
        return n.Not(children[0], self._pos(meta))

    def compare(self, meta: Any, children: list[Any]) -> n.Compare:
        left, op, right = children
        return n.Compare(n.CompareOp(str(op)), left, right, self._pos(meta))

    def member(self, meta: Any, children: list[Any]) -> n.Member:
        return n.Member(children[0], children[1], False, self._pos(meta))

    def not_member(self, meta: Any, children: list[Any]) -> n.Member:
        return n.Member(children[0], children[1], True, self._pos(meta))

    def param(self, meta: Any, children: list[Any]) -> n.Param:
        token: Token = children[0]
        parts = str(token).split(".")
        line, column = token.line or 1, token.column or 1
        if len(parts) != 3:
            raise _Invalid(
                line,
                column,
                f"'{token}': write params.user.NAME, params.robot.NAME or params.env.NAME",
            )
        profile = _PROFILES.get(parts[1])
        if profile is None:
            raise _Invalid(
                line, column + 7, f"unknown profile '{parts[1]}' (use user, robot or env)"
            )
        return n.Param(profile, parts[2], self._pos(meta))

    def name(self, meta: Any, children: list[Any]) -> n.Name:
        return n.Name(str(children[0]), self._pos(meta))

    def set_(self, meta: Any, children: list[Any]) -> n.SetLiteral:
        items = tuple(child for child in children if child is not None)
        return n.SetLiteral(items, self._pos(meta))

    def string(self, meta: Any, children: list[Any]) -> n.String:
        return n.String(_unquote(children[0]), self._pos(meta))

    def number(self, meta: Any, children: list[Any]) -> n.Number:
        token: Token = children[0]
        text = str(token)
        value: int | float
        if "." in text or "e" in text or "E" in text:
            value = float(text)
            if not math.isfinite(value):
                raise _Invalid(token.line or 1, token.column or 1, f"number {text} is too large")
        else:
            value = int(text)
        return n.Number(value, self._pos(meta))

    def true(self, meta: Any, children: list[Any]) -> n.Boolean:
        return n.Boolean(True, self._pos(meta))

    def false(self, meta: Any, children: list[Any]) -> n.Boolean:
        return n.Boolean(False, self._pos(meta))


def _describe(token: Token) -> str:
    if token.type == "$END":
        return "end of file"
    text = str(token)
    if len(text) > 30:
        text = text[:27] + "..."
    return f"'{text}'"


def _expected(names: set[str]) -> str:
    readable = sorted(
        {_TOKEN_NAMES.get(name, f"'{name.lower()}'") for name in names if not name.startswith("_")}
    )
    if not readable:
        return ""
    if len(readable) > 6:
        readable = [*readable[:6], "..."]
    return "; expected " + ", ".join(readable)


def _end_position(text: str) -> tuple[int, int]:
    lines = text.split("\n")
    return len(lines), len(lines[-1]) + 1


def _syntax_problem(error: UnexpectedInput, text: str, file: str, lines: list[str]) -> Problem:
    line, column = error.line, error.column
    if isinstance(error, UnexpectedToken):
        message = f"unexpected {_describe(error.token)}{_expected(set(error.expected))}"
        if error.token.type == "$END" or line is None or line < 1:
            line, column = _end_position(text)
    elif isinstance(error, UnexpectedCharacters):
        index = error.pos_in_stream if error.pos_in_stream is not None else -1
        char = text[index] if 0 <= index < len(text) else "?"
        message = f"unexpected character {char!r}"
    else:
        message = "syntax error"
        if line is None or line < 1:
            line, column = _end_position(text)
    return Problem.at(n.Pos(file, line, column), f"syntax error: {message}", lines)


def parse(text: str, file: str = "<rules>") -> n.Program:
    """Parse DMSL text; ``file`` names it in positions and problems.

    Raises:
        RulesError: the text is not DMSL (with line, column and what was expected).
    """
    lines = text.splitlines()
    try:
        tree = _parser().parse(text)
        program: n.Program = _Build(file).transform(tree)
    except UnexpectedInput as error:
        raise RulesError([_syntax_problem(error, text, file, lines)]) from None
    except VisitError as error:
        inner = error.orig_exc
        if isinstance(inner, _Invalid):
            raise RulesError(
                [Problem.at(n.Pos(file, inner.line, inner.column), inner.message, lines)]
            ) from None
        if isinstance(inner, RecursionError):
            raise RulesError([Problem.at(n.Pos(file, 1, 1), _TOO_DEEP, lines)]) from None
        raise
    except RecursionError:
        raise RulesError([Problem.at(n.Pos(file, 1, 1), _TOO_DEEP, lines)]) from None
    return program
