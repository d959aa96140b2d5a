"""How much work a condition may cost once its ``def`` names are written out.

The verifier's flow analysis and the compiled rules both follow a ``def`` name into its
expression each time it is used, so a ``def`` that uses the previous one twice doubles
the work with each line: forty such lines (a kilobyte) would never finish. Rules whose
``def`` or condition stands for more than :data:`MAX_TERMS` terms are refused with a
finding at that line instead; hand-written rules stay far below it.
"""

from __future__ import annotations

from collections.abc import Collection, Iterable, Iterator, Mapping

from dms.rules import nodes as n

MAX_TERMS = 10_000
"""The terms one ``def`` or condition may stand for with every ``def`` it uses written out
(checking or evaluating one costs about that many steps)."""

MAX_TOTAL_TERMS = 100_000
"""The terms all the conditions of the rules may stand for together, for the same reason."""

TOO_COMPLEX = "too complex to verify here"


def _walk(expr: n.Expr) -> Iterator[n.Expr]:
    stack = [expr]
    while stack:
        node = stack.pop()
        yield node
        if isinstance(node, n.Compare | n.And | n.Or):
            stack.extend((node.left, node.right))
        elif isinstance(node, n.Member):
            stack.extend((node.element, node.collection))
        elif isinstance(node, n.Not):
            stack.append(node.operand)


class TermCounter:
    """Counts terms with ``def`` names written out, each ``def`` counted once (memo).

    ``skip`` are names not to follow (unknown, or on a ``def`` cycle: reported already).
    Counts stop just above :data:`MAX_TERMS`, so they stay small numbers.
    """

    def __init__(self, definitions: Mapping[str, n.Definition], skip: Collection[str]) -> None:
        self.definitions = definitions
        self.skip = skip
        self._named: dict[str, int] = {}

    def _followed(self, node: n.Expr) -> str | None:
        """The ``def`` name ``node`` stands for, when it is one to write out."""
        if isinstance(node, n.Name) and node.name in self.definitions:
            return None if node.name in self.skip else node.name
        return None

    def count(self, expr: n.Expr) -> int:
        """Terms of ``expr`` with its ``def`` names written out (at most MAX_TERMS + 1)."""
        total = 0
        for node in _walk(expr):
            total += 1
            name = self._followed(node)
            if name is not None:
                total += self.named(name)
            if total > MAX_TERMS:
                return MAX_TERMS + 1
        return total

    def named(self, name: str) -> int:
        """Terms of ``def name``'s expression written out."""
        if name not in self._named:
            self._named[name] = 0  # a cycle (never here: ``skip`` has them) counts nothing
            self._named[name] = self.count(self.definitions[name].expr)
        return self._named[name]

    def too_big(self, expr: n.Expr) -> bool:
        """Whether ``expr`` is over the budget by itself, not only through a ``def`` that
        is (that ``def`` is reported at its own line)."""
        if self.count(expr) <= MAX_TERMS:
            return False
        names = (self._followed(node) for node in _walk(expr))
        return not any(name is not None and self.named(name) > MAX_TERMS for name in names)


def oversized(
    definitions: Mapping[str, n.Definition],
    conditions: Iterable[n.Expr],
    skip: Collection[str],
) -> Iterator[tuple[n.Pos, str]]:
    """``(where, message)`` for each ``def`` and condition over :data:`MAX_TERMS` terms.

    Only the first one over the budget on a chain of ``def``s is named: the ones that
    use it are too big because of it. Past :data:`MAX_TOTAL_TERMS` for all the
    conditions together, the condition that crosses it is named.
    """
    counter = TermCounter(definitions, skip)
    for name, definition in definitions.items():
        if name not in skip and counter.too_big(definition.expr):
            yield (
                definition.pos,
                f"{TOO_COMPLEX}: '{name}' stands for more than {MAX_TERMS} terms once the "
                "defs it uses are written out (each use of a def counts it again)",
            )
    total = 0
    for cond in conditions:
        if counter.too_big(cond):
            yield (
                cond.pos,
                f"{TOO_COMPLEX}: this condition stands for more than {MAX_TERMS} terms once "
                "the defs it uses are written out (each use of a def counts it again)",
            )
        total += counter.count(cond)
        if total > MAX_TOTAL_TERMS:
            yield (
                cond.pos,
                f"{TOO_COMPLEX}: the conditions up to here stand for more than "
                f"{MAX_TOTAL_TERMS} terms together once the defs they use are written out",
            )
            return
