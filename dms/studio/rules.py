"""The rules pane: the DMSL files beside the behaviors, checked as ``dms rules check`` does.

The page sends the text being edited; :func:`check_text` checks it together with the
other rules files (one namespace across them, as the daemon loads them) with the same
steps as :func:`dms.rules.loader.lint_files`: parse each file, verify them together,
and look for warnings only in rules without problems. Each finding comes back with its
line and column, and as the line ``dms rules check`` prints, so the two agree.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from dms.rules.loader import parse_all
from dms.rules.problems import Problem
from dms.rules.verifier import activation_warnings
from dms.studio.errors import StudioError
from dms.studio.folder import digest, write_atomically


@dataclass(frozen=True)
class RulesFiles:
    """The rules files the studio edits: named on the command line, or the ``*.dmsl``
    files of the behaviors folder."""

    paths: tuple[Path, ...]

    def names(self) -> list[str]:
        return [path.name for path in self.paths]

    def path(self, name: str) -> Path:
        for path in self.paths:
            if path.name == name:
                return path
        raise StudioError(f"no rules file {name!r}: the studio edits {self.names()}", 404)

    def open(self, name: str) -> dict[str, Any]:
        path = self.path(name)
        try:
            data = path.read_bytes()
        except OSError as error:
            raise StudioError(f"{path}: {error.strerror or error}", 404) from None
        text = data.decode("utf-8", errors="replace")
        return {"name": name, "file": str(path), "text": text, "hash": digest(data)}

    def check(self, name: str, text: str) -> dict[str, Any]:
        """The findings of ``text`` as file ``name``, checked with the other files."""
        edited = self.path(name)
        sources = [(str(edited), text)]
        for path in self.paths:
            if path != edited:
                try:
                    sources.append((str(path), path.read_text(encoding="utf-8")))
                except (OSError, UnicodeDecodeError) as error:
                    reason = getattr(error, "strerror", None) or error
                    raise StudioError(f"{path}: cannot read: {reason}", 422) from None
        problems, warnings = lint_sources(sources)
        return {
            "ok": not problems,
            "findings": [
                finding(problem, "error") for problem in problems if problem.file == str(edited)
            ]
            + [finding(warning, "warning") for warning in warnings if warning.file == str(edited)],
            "elsewhere": [str(problem) for problem in problems if problem.file != str(edited)],
        }

    def save(self, name: str, text: str, opened_hash: str | None) -> dict[str, Any]:
        """Write ``text`` into the file when it verifies: the daemon refuses to start on
        rules that do not (and a reload keeps the old ones)."""
        path = self.path(name)
        report = self.check(name, text)
        if not report["ok"]:
            errors = sum(1 for item in report["findings"] if item["severity"] == "error")
            shown = errors or len(report["elsewhere"])
            raise StudioError(f"not saved: {shown} problem(s); the file is unchanged", 422)
        try:
            current = path.read_bytes()
        except FileNotFoundError:
            current = None
        if current is not None and digest(current) != opened_hash:
            raise StudioError(
                f"{path.name} changed on disk since it was opened: open it again", 409
            )
        write_atomically(path, text)
        return {**report, "hash": digest(text.encode("utf-8"))}


def finding(problem: Problem, severity: str) -> dict[str, Any]:
    """One finding for the page: where, what, and the line ``dms rules check`` prints."""
    message = problem.message.removeprefix("warning: ")
    return {
        "line": problem.line,
        "column": problem.column,
        "message": message,
        "severity": severity,
        "text": str(problem),
    }


def lint_sources(sources: Sequence[tuple[str, str]]) -> tuple[list[Problem], list[Problem]]:
    """``(problems, warnings)`` of ``(file, text)`` pairs checked together."""
    programs, problems = parse_all(sources, None)
    if problems:
        return problems, []
    return problems, activation_warnings(programs)


def rules_files(folder: Path, named: Sequence[Path]) -> RulesFiles:
    """The files named (``--rules``), else the ``*.dmsl`` files of ``folder``."""
    paths = [path.resolve() for path in named] or sorted(folder.glob("*.dmsl"))
    return RulesFiles(tuple(paths))
