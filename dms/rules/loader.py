"""Rules files to a verified :class:`RuleSet`, and :class:`LiveRules` for the daemon."""

from __future__ import annotations

import threading
from collections.abc import Collection, Sequence
from pathlib import Path

from dms.rules import nodes as n
from dms.rules.compiler import Params, RuleResult, RuleSet
from dms.rules.parser import parse
from dms.rules.problems import Problem, RulesError
from dms.rules.schema import ParameterSchema
from dms.rules.verifier import activation_warnings, outcome_problems, verify


def _read(path: Path) -> tuple[str | None, Problem | None]:
    try:
        return Path(path).read_text(encoding="utf-8"), None
    except UnicodeDecodeError as error:
        return None, Problem(str(path), 1, 1, f"not UTF-8 text: {error.reason}")
    except OSError as error:
        return None, Problem(str(path), 1, 1, f"cannot read: {error.strerror or error}")


def parse_all(
    sources: Sequence[tuple[str, str]], schema: ParameterSchema | None
) -> tuple[tuple[n.Program, ...], list[Problem]]:
    """The programs of ``(file, text)`` pairs checked together, and their problems (what
    ``dms rules check``, a reload and the studio's rules pane all report)."""
    programs: list[n.Program] = []
    problems: list[Problem] = []
    for file, text in sources:
        try:
            programs.append(parse(text, file))
        except RulesError as error:
            problems.extend(error.problems)
    lines = {file: text.splitlines() for file, text in sources}
    problems.extend(verify(programs, schema, lines))
    return tuple(programs), problems


def _read_all(paths: Sequence[Path]) -> tuple[list[tuple[str, str]], list[Problem]]:
    sources: list[tuple[str, str]] = []
    problems: list[Problem] = []
    for path in paths:
        text, problem = _read(path)
        if problem is not None:
            problems.append(problem)
        else:
            assert text is not None
            sources.append((str(path), text))
    return sources, problems


def check_files(paths: Sequence[Path], schema: ParameterSchema | None = None) -> list[Problem]:
    """Every problem of the rules files checked together; never raises for bad content."""
    return lint_files(paths, schema)[0]


def lint_files(
    paths: Sequence[Path], schema: ParameterSchema | None = None
) -> tuple[list[Problem], list[Problem]]:
    """``(problems, warnings)`` of the rules files checked together.

    Warnings (components that may activate nothing on some path) are looked for only in
    rules without problems; they never make the rules invalid.
    """
    sources, problems = _read_all(paths)
    programs, found = parse_all(sources, schema)
    problems += found
    if problems:
        return problems, []
    return problems, activation_warnings(programs)


def load_rules(paths: Sequence[Path], schema: ParameterSchema | None = None) -> RuleSet:
    """Parse, verify and compile rules files (one namespace across the files).

    Raises:
        RulesError: a file cannot be read, does not parse or does not verify.
    """
    sources, problems = _read_all(paths)
    programs, found = parse_all(sources, schema)
    problems += found
    if problems:
        raise RulesError(problems)
    return RuleSet(programs)


def rules_from_text(
    text: str, file: str = "<rules>", schema: ParameterSchema | None = None
) -> RuleSet:
    """Rules from a string (tests, benchmarks, tools); raises :class:`RulesError`."""
    programs, problems = parse_all([(file, text)], schema)
    if problems:
        raise RulesError(problems)
    return RuleSet(programs)


def check_outcomes(ruleset: RuleSet, component: str, outcomes: Collection[str]) -> list[Problem]:
    """Activations of ``component`` (and what it evaluates) that are not in ``outcomes``.

    A behavior's decision state calls this with its declared outcomes when it loads.
    """
    return outcome_problems(ruleset.component_nodes, component, outcomes)


class LiveRules:
    """The daemon's rules: reloadable, thread-safe, keeping the old rules on failure."""

    def __init__(self, paths: Sequence[Path], schema: ParameterSchema | None = None) -> None:
        """Load ``paths``; raises :class:`RulesError` when they do not verify."""
        self.paths = tuple(Path(path) for path in paths)
        self.schema = schema
        self._lock = threading.Lock()
        self._current = load_rules(self.paths, schema)

    @property
    def current(self) -> RuleSet:
        """The rules in force."""
        with self._lock:
            return self._current

    def reload(self) -> list[Problem]:
        """Read the files again (on SIGHUP or a ``reload_rules`` request).

        Returns:
            No problems when the new rules are in force; otherwise the problems, and the
            old rules stay.
        """
        try:
            fresh = load_rules(self.paths, self.schema)
        except RulesError as error:
            return error.problems
        with self._lock:
            self._current = fresh
        return []

    def check_outcomes(self, component: str, outcomes: Collection[str]) -> list[Problem]:
        """:func:`check_outcomes` on the rules in force (a decide state's outcomes)."""
        return check_outcomes(self.current, component, outcomes)

    def evaluate(self, component: str, params: Params) -> RuleResult | None:
        """``component``'s decision, or ``None`` when no rule defines it (built-in logic)."""
        rules = self.current
        if not rules.defines(component):
            return None
        return rules.evaluate(component, params)
