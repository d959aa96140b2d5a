"""What the verifier reports: :class:`Problem`, and :class:`RulesError` that carries them."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from dms.kernel.errors import DmsError
from dms.rules.nodes import Pos


@dataclass(frozen=True, slots=True)
class Problem:
    """One thing wrong with a rules file, at ``file:line:column``.

    ``source_line`` is the text of that line when known, for :meth:`excerpt`.
    """

    file: str
    line: int
    column: int
    message: str
    source_line: str | None = field(default=None, compare=False, repr=False)

    def __str__(self) -> str:
        return f"{self.file}:{self.line}:{self.column}: {self.message}"

    @classmethod
    def at(cls, pos: Pos, message: str, lines: list[str] | None = None) -> Problem:
        """A problem at ``pos``, keeping the source line when ``lines`` are given."""
        text = None
        if lines is not None and 1 <= pos.line <= len(lines):
            text = lines[pos.line - 1]
        return cls(pos.file, pos.line, pos.column, message, text)

    def excerpt(self) -> str:
        """The source line and a caret under the column (empty when the line is unknown)."""
        text = self.source_line
        if text is None:
            text = _read_line(self.file, self.line)
        if text is None:
            return ""
        text = text.rstrip("\r\n")
        prefix = text[: max(self.column - 1, 0)]
        pad = "".join("\t" if char == "\t" else " " for char in prefix)
        return f"{text}\n{pad}^"


def _read_line(file: str, line: int) -> str | None:
    try:
        lines = Path(file).read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError):
        return None
    return lines[line - 1] if 1 <= line <= len(lines) else None


class RulesError(DmsError):
    """Rules that do not parse or verify; ``problems`` lists every one of them."""

    def __init__(self, problems: list[Problem]) -> None:
        self.problems = list(problems)
        first = str(self.problems[0]) if self.problems else "invalid rules"
        more = len(self.problems) - 1
        super().__init__(first + (f" (and {more} more)" if more > 0 else ""))
