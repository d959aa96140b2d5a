"""Rules too big to check once their ``def``s are written out are refused, quickly.

A ``def`` that uses the previous one twice doubles the work with each line; the
verifier names the first such ``def`` (or condition) over the budget at its line
instead of running for ever, from Python and through ``dms rules check``.
"""

from __future__ import annotations

import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

from dms.rules import check_files, rules_from_text
from dms.rules.budget import MAX_TERMS, MAX_TOTAL_TERMS, TOO_COMPLEX

Write = Callable[..., Path]


def doubling(lines: int, condition: str = "d{last}") -> str:
    """``def d0`` then each ``def`` using the previous one twice; one component."""
    text = ["def d0 params.user.age > 3"]
    text += [f"def d{i} d{i - 1} and not d{i - 1}" for i in range(1, lines)]
    text.append(
        f'component C [ if {condition.format(last=lines - 1)} then activate "a" else activate "b" ]'
    )
    return "\n".join(text) + "\n"


def test_a_doubling_bomb_is_refused_at_the_first_def_over_the_budget(write: Write) -> None:
    path = write(doubling(40))  # two to the fortieth terms: never finishes unbounded
    started = time.monotonic()
    problems = check_files([path])
    assert time.monotonic() - started < 5
    # d_i stands for 8 * 2**i - 4 terms: d11 is the first over 10,000
    assert [str(p) for p in problems] == [
        f"{path}:12:1: {TOO_COMPLEX}: 'd11' stands for more than {MAX_TERMS} terms once the "
        "defs it uses are written out (each use of a def counts it again)"
    ]


def test_rules_just_under_the_budget_are_checked_and_run(write: Write) -> None:
    assert MAX_TERMS >= 8 * 2**10 - 4  # d10
    rules = rules_from_text(doubling(11))
    result = rules.evaluate("C", {"user": {"age": 40}})
    assert result.activate == ("b",)  # d10 is false: x and not x


def test_a_condition_over_the_budget_by_itself_is_named(write: Write) -> None:
    path = write(doubling(11, condition="d{last} or d{last}"))
    assert [str(p) for p in check_files([path])] == [
        f"{path}:12:18: {TOO_COMPLEX}: this condition stands for more than {MAX_TERMS} "
        "terms once the defs it uses are written out (each use of a def counts it again)"
    ]


def test_many_big_conditions_together_are_refused(write: Write) -> None:
    text = ["def d0 params.user.age > 3"]
    text += [f"def d{i} d{i - 1} and not d{i - 1}" for i in range(1, 11)]
    count = MAX_TOTAL_TERMS // MAX_TERMS * 2
    text += [f'component C{k} [ if d10 then activate "a" else activate "b" ]' for k in range(count)]
    path = write("\n".join(text) + "\n")
    problems = check_files([path])
    assert len(problems) == 1
    assert TOO_COMPLEX in problems[0].message and "together" in problems[0].message
    assert problems[0].line > 12  # a component line, past the defs


def test_dms_rules_check_refuses_the_bomb_within_seconds(write: Write) -> None:
    path = write(doubling(40))
    started = time.monotonic()
    done = subprocess.run(
        [sys.executable, "-m", "dms.cli", "rules", "check", str(path)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    elapsed = time.monotonic() - started
    assert done.returncode == 1, done.stderr
    assert f"{path}:12:1: {TOO_COMPLEX}" in done.stdout
    assert elapsed < 5, f"took {elapsed:.1f} s"
