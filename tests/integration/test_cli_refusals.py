"""The operator's command line as a person meets it: the real ``dms`` in a subprocess,
on real SQLite files. Every refusal is one ``dms: ...`` line and a non-zero exit.

Covers: a database that does not exist is refused, never created (only ``dms run`` and
``dms db upgrade`` create one); ``users erase`` asks on a terminal and needs ``--yes``
elsewhere; ``users add --set`` takes profile fields only, ``--extra`` the free
attributes; ``--version``; shell completion; choices refused by typer.
"""

from __future__ import annotations

import json
import os
import pty
import subprocess
import sys
from importlib.metadata import version
from pathlib import Path

import pytest

pytestmark = pytest.mark.integration

_SCRIPT = Path(sys.executable).with_name("dms")
DMS = [str(_SCRIPT)] if _SCRIPT.exists() else [sys.executable, "-m", "dms.cli"]
"""The installed console script (what a person types); the module where it is not."""


def dms(
    *args: str, env: dict[str, str] | None = None, stdin: int | None = subprocess.DEVNULL
) -> subprocess.CompletedProcess[str]:
    clean = {k: v for k, v in os.environ.items() if not k.startswith("DMS_")}
    return subprocess.run(
        [*DMS, *args],
        capture_output=True,
        text=True,
        timeout=120,
        stdin=stdin,
        env={**clean, **(env or {})},
    )


def one_line_refusal(result: subprocess.CompletedProcess[str], *words: str) -> str:
    assert result.returncode == 1, (result.returncode, result.stdout, result.stderr)
    line = result.stderr.strip()
    assert "\n" not in line and line.startswith("dms: "), result.stderr
    for word in words:
        assert word in line, line
    return line


@pytest.fixture
def db(tmp_path: Path) -> str:
    """A database made the way an operator makes one: ``dms db upgrade``."""
    path = tmp_path / "dms.db"
    made = dms("db", "upgrade", "--db", str(path))
    assert made.returncode == 0, made.stderr
    assert path.exists()
    return str(path)


READERS = [
    ("users", "list"),
    ("users", "show", "ann"),
    ("users", "export", "ann"),
    ("users", "erase", "ann", "--yes"),
    ("users", "add", "ann", "--set", "age=81"),
    ("agenda", "list"),
    ("agenda", "missed"),
    ("agenda", "remove", "1"),
    ("agenda", "add", "--user", "ann", "--reminder", "Pills", "--every", "3600"),
    ("sessions", "list"),
    ("sessions", "export"),
]


@pytest.mark.parametrize("command", READERS, ids=lambda c: " ".join(c[:2]))
def test_a_database_that_does_not_exist_is_refused_and_not_created(
    tmp_path: Path, command: tuple[str, ...]
) -> None:
    missing = tmp_path / "nowhere" / "x.db"
    one_line_refusal(dms(*command, "--db", f"sqlite:///{missing}"), f"no database at {missing}")
    assert not missing.parent.exists()


def test_a_plain_path_and_dms_db_are_refused_the_same_way(tmp_path: Path) -> None:
    missing = tmp_path / "nowhere" / "x.db"
    one_line_refusal(dms("users", "list", "--db", str(missing)), f"no database at {missing}")
    one_line_refusal(dms("users", "list", env={"DMS_DB": str(missing)}), "no database at")
    assert not missing.parent.exists()


def test_db_upgrade_creates_it_then_the_listings_are_tables(db: str) -> None:
    added = dms("users", "add", "ann", "--set", "name=Ann", "--set", "age=81", "--db", db)
    assert added.returncode == 0, added.stderr
    listed = dms("users", "list", "--db", db)
    assert listed.returncode == 0, listed.stderr
    header = next(line for line in listed.stdout.splitlines() if "name" in line)
    assert all(column in header for column in ("id", "name", "age", "proactivity"))
    assert any(
        "ann" in line and "Ann" in line and "81" in line for line in listed.stdout.splitlines()
    )
    assert json.loads(dms("users", "list", "--json", "--db", db).stdout) == {"users": ["ann"]}
    agenda = dms(
        "agenda", "add", "--user", "ann", "--reminder", "Pills", "--every", "3600", "--db", db
    )
    assert agenda.returncode == 0, agenda.stderr
    table = dms("agenda", "list", "--db", db).stdout
    assert "Pills" in table and "priority" in table and "normal" in table


def test_users_add_takes_profile_fields_only(db: str) -> None:
    assert dms("users", "add", "bob", "--db", db).returncode == 0
    line = one_line_refusal(dms("users", "add", "bob", "--set", "agee=81", "--db", db), "agee")
    assert "did you mean age" in line and "--extra" in line
    one_line_refusal(dms("users", "add", "bob", "--extra", "age=81", "--db", db), "--set age")
    one_line_refusal(dms("users", "add", "bob", "--set", "age", "--db", db), "NAME=VALUE")
    shown = json.loads(dms("users", "show", "bob", "--db", db).stdout)
    assert shown["age"] is None and shown["attributes"] == {}  # nothing of it was stored
    added = dms("users", "add", "bob", "--set", "age=81", "--extra", "pet=cat", "--db", db)
    assert added.returncode == 0, added.stderr
    profile = json.loads(added.stdout)
    assert (profile["age"], profile["attributes"]) == (81, {"pet": "cat"})


def test_users_erase_needs_yes_off_a_terminal(db: str) -> None:
    assert dms("users", "add", "ann", "--db", db).returncode == 0
    one_line_refusal(dms("users", "erase", "ann", "--db", db), "--yes")
    assert json.loads(dms("users", "list", "--json", "--db", db).stdout) == {"users": ["ann"]}
    one_line_refusal(dms("users", "erase", "nobody", "--yes", "--db", db), "nobody")
    erased = dms("users", "erase", "ann", "--yes", "--db", db)
    assert erased.returncode == 0 and "erased ann" in erased.stdout
    assert json.loads(dms("users", "list", "--json", "--db", db).stdout) == {"users": []}


@pytest.mark.parametrize(("answer", "kept"), [("n", True), ("y", False)])
def test_users_erase_asks_on_a_terminal(db: str, answer: str, kept: bool) -> None:
    assert dms("users", "add", "ann", "--db", db).returncode == 0
    controller, terminal = pty.openpty()
    try:
        os.write(controller, f"{answer}\n".encode())  # typed before the question: it waits
        result = dms("users", "erase", "ann", "--db", db, stdin=terminal)
    finally:
        os.close(terminal)
        os.close(controller)
    assert "Erase everything stored about ann" in result.stdout
    if kept:
        one_line_refusal(result, "not confirmed")
    else:
        assert result.returncode == 0, result.stderr
    users = json.loads(dms("users", "list", "--json", "--db", db).stdout)["users"]
    assert users == (["ann"] if kept else [])


def test_version_and_completion() -> None:
    shown = dms("--version")
    assert (shown.returncode, shown.stdout.strip()) == (0, f"dms {version('dms')}")
    if DMS[0] != str(_SCRIPT):
        pytest.skip("completion answers for the installed console script")
    complete = {"_DMS_COMPLETE": "complete_bash", "COMP_CWORD": "1", "COMP_WORDS": "dms us"}
    assert dms(env=complete).stdout.split() == ["users"]
    levels = {**complete, "COMP_CWORD": "3", "COMP_WORDS": "dms run --log-level "}
    assert dms(env=levels).stdout.split() == ["debug", "info", "warning", "error"]


def test_help_shows_choices_defaults_and_variables() -> None:
    shown = dms("run", "--help", env={"COLUMNS": "200"}).stdout
    for text in ("sim|zenoh", "debug|info|warning|error", "text|json", "DMS_ROBOT_ID", "mini"):
        assert text in shown, text
    priority = dms("agenda", "add", "--help", env={"COLUMNS": "200"}).stdout
    assert "normal|high" in priority and "default: normal" in priority


@pytest.mark.parametrize(
    "args",
    [
        ("run", "--robot", "nao"),
        ("run", "--log-format", "xml"),
        (
            "agenda",
            "add",
            "--user",
            "ann",
            "--reminder",
            "x",
            "--every",
            "60",
            "--priority",
            "urgent",
        ),
    ],
)
def test_a_choice_outside_its_list_is_a_usage_error(args: tuple[str, ...]) -> None:
    result = dms(*args)
    assert result.returncode == 2
    assert "Invalid value for '--" in result.stderr
