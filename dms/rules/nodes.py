"""The DMSL syntax tree: frozen, slotted dataclasses built by :mod:`dms.rules.parser`.

Positions (:class:`Pos`) never take part in equality, so two programs that say the same
thing compare equal wherever they were written; the pretty-printer relies on that.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import StrEnum


@dataclass(frozen=True, slots=True)
class Pos:
    """Where a node starts: file name, 1-based line and column."""

    file: str = "<rules>"
    line: int = 1
    column: int = 1


NOWHERE = Pos()


class Profile(StrEnum):
    """The three profiles a parameter belongs to (``params.<profile>.<name>``)."""

    USER = "user"
    ROBOT = "robot"
    ENV = "env"


class CompareOp(StrEnum):
    """Comparison operators; ``=`` and ``!=`` take any kind, the others numbers."""

    EQ = "="
    NE = "!="
    LT = "<"
    LE = "<="
    GT = ">"
    GE = ">="


# ----------------------------------------------------------------- expressions


@dataclass(frozen=True, slots=True)
class Number:
    """A number literal (int or float; ``1`` and ``1.0`` are the same number)."""

    value: int | float
    pos: Pos = field(default=NOWHERE, compare=False, repr=False)


@dataclass(frozen=True, slots=True)
class String:
    """A double-quoted string literal."""

    value: str
    pos: Pos = field(default=NOWHERE, compare=False, repr=False)


@dataclass(frozen=True, slots=True)
class Boolean:
    """``true`` or ``false``."""

    value: bool
    pos: Pos = field(default=NOWHERE, compare=False, repr=False)


Literal = Number | String | Boolean


@dataclass(frozen=True, slots=True)
class SetLiteral:
    """``{literal, ...}``: a set of numbers, strings or booleans."""

    items: tuple[Literal, ...]
    pos: Pos = field(default=NOWHERE, compare=False, repr=False)


@dataclass(frozen=True, slots=True)
class Param:
    """``params.<profile>.<name>``: bound when the rule runs; missing means unknown."""

    profile: Profile
    name: str
    pos: Pos = field(default=NOWHERE, compare=False, repr=False)

    @property
    def key(self) -> str:
        """The name reported in ``missing``, like ``user.age``."""
        return f"{self.profile.value}.{self.name}"


@dataclass(frozen=True, slots=True)
class Name:
    """A reference to a ``def``: a constant, a set or a named condition."""

    name: str
    pos: Pos = field(default=NOWHERE, compare=False, repr=False)


@dataclass(frozen=True, slots=True)
class Compare:
    """``left <op> right``."""

    op: CompareOp
    left: Expr
    right: Expr
    pos: Pos = field(default=NOWHERE, compare=False, repr=False)


@dataclass(frozen=True, slots=True)
class Member:
    """``element in collection`` (``negated``: ``element not in collection``)."""

    element: Expr
    collection: Expr
    negated: bool = False
    pos: Pos = field(default=NOWHERE, compare=False, repr=False)


@dataclass(frozen=True, slots=True)
class Not:
    """``not operand`` (Kleene: ``not unknown`` is unknown)."""

    operand: Expr
    pos: Pos = field(default=NOWHERE, compare=False, repr=False)


@dataclass(frozen=True, slots=True)
class And:
    """``left and right`` (Kleene: ``false and unknown`` is false)."""

    left: Expr
    right: Expr
    pos: Pos = field(default=NOWHERE, compare=False, repr=False)


@dataclass(frozen=True, slots=True)
class Or:
    """``left or right`` (Kleene: ``true or unknown`` is true)."""

    left: Expr
    right: Expr
    pos: Pos = field(default=NOWHERE, compare=False, repr=False)


Expr = Number | String | Boolean | SetLiteral | Param | Name | Compare | Member | Not | And | Or

# ------------------------------------------------------------------ statements


@dataclass(frozen=True, slots=True)
class Activate:
    """``activate "name"``: the decision's outcome."""

    name: str
    pos: Pos = field(default=NOWHERE, compare=False, repr=False)


@dataclass(frozen=True, slots=True)
class Cancel:
    """``cancel "name"``."""

    name: str
    pos: Pos = field(default=NOWHERE, compare=False, repr=False)


@dataclass(frozen=True, slots=True)
class Evaluate:
    """``evaluate Component``: splices in that component's commands."""

    component: str
    pos: Pos = field(default=NOWHERE, compare=False, repr=False)


@dataclass(frozen=True, slots=True)
class Block:
    """``[ statement* ]``; the parser turns a one-statement block into the statement."""

    body: tuple[Stmt, ...]
    pos: Pos = field(default=NOWHERE, compare=False, repr=False)


@dataclass(frozen=True, slots=True)
class If:
    """``if cond then then_ [else else_]``: ``then_`` runs only when cond is true."""

    cond: Expr
    then: Stmt
    else_: Stmt | None = None
    pos: Pos = field(default=NOWHERE, compare=False, repr=False)


Stmt = Activate | Cancel | Evaluate | Block | If

# --------------------------------------------------------------------- program


@dataclass(frozen=True, slots=True)
class Definition:
    """``def NAME expr``."""

    name: str
    expr: Expr
    pos: Pos = field(default=NOWHERE, compare=False, repr=False)


@dataclass(frozen=True, slots=True)
class Component:
    """``component NAME [ statement* ]``: the decision block of one component."""

    name: str
    body: tuple[Stmt, ...]
    pos: Pos = field(default=NOWHERE, compare=False, repr=False)


@dataclass(frozen=True, slots=True)
class Program:
    """One rules file: its definitions and components in the order written."""

    items: tuple[Definition | Component, ...]

    @property
    def definitions(self) -> tuple[Definition, ...]:
        """The ``def`` items."""
        return tuple(item for item in self.items if isinstance(item, Definition))

    @property
    def components(self) -> tuple[Component, ...]:
        """The ``component`` items."""
        return tuple(item for item in self.items if isinstance(item, Component))
