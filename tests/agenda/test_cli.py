"""``dms agenda list|add|remove|missed`` on a real SQLite file.

The commands run through the agenda's typer app; errors come out as the agenda's
one-line exceptions, which ``dms.cli.main`` prints as ``dms: <message>``.
"""

from __future__ import annotations

import json
from datetime import UTC, datetime, timedelta

import pytest
from typer.testing import CliRunner

from agenda import AgendaError, AgendaNotFound
from agenda.cli import app
from memory import ProfileStore

FUTURE = (datetime.now(UTC) + timedelta(days=30)).replace(microsecond=0, tzinfo=None)


def _run(*args: str) -> tuple[int, str, BaseException | None]:
    result = CliRunner().invoke(app, list(args))
    error = result.exception if not isinstance(result.exception, SystemExit) else None
    return result.exit_code, result.output, error


@pytest.fixture
def db(db_url: str) -> list[str]:
    """A profile store where "ann" and "bob" exist: the CLI refuses unknown users."""
    store = ProfileStore(db_url)
    for user in ("ann", "bob"):
        store.get_or_create(user, datetime.now(UTC))
    store.close()
    return ["--db", db_url]


def test_add_list_remove(db: list[str]) -> None:
    code, out, _ = _run(
        "add",
        "--user",
        "ann",
        "--reminder",
        "The doctor at five",
        "--at",
        FUTURE.isoformat(timespec="minutes"),
        "--tz",
        "Europe/Madrid",
        "--priority",
        "high",
        "--lead",
        "600",
        "--grace",
        "900",
        *db,
    )
    assert code == 0 and out.startswith("added agenda item 1: next at ")
    code, out, _ = _run(
        "add",
        "--user",
        "ann",
        "--event",
        "cognitive_stimulation",
        "--cron",
        "0 10 * * MON",
        "--json",
        *db,
    )
    assert code == 0
    assert json.loads(out)["item"]["schedule"] == "cron"
    assert _run("add", "--user", "bob", "--event", "talk", "--every", "3600", *db)[0] == 0

    code, out, _ = _run("list", "--json", *db)
    items = json.loads(out)["items"]
    assert code == 0 and len(items) == 3
    doctor = next(i for i in items if i["id"] == 1)
    assert (doctor["priority"], doctor["lead_s"], doctor["grace_s"]) == ("high", 600, 900)
    assert doctor["next_fire_local"].startswith(FUTURE.isoformat(timespec="minutes"))

    code, out, _ = _run("list", "--user", "bob", *db)
    assert code == 0 and "talk" in out and "doctor" not in out

    assert _run("remove", "1", *db)[:2] == (0, "removed agenda item 1\n")
    code, out, _ = _run("list", "--user", "ann", "--json", *db)
    assert [i["id"] for i in json.loads(out)["items"]] == [2]
    assert _run("missed", *db)[1] == "nothing missed\n"


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--reminder", "x"], "exactly one of at, cron or every"),
        (["--reminder", "x", "--event", "quiz", "--every", "60"], "exactly one of --reminder"),
        (["--event", "juggling", "--every", "60"], "unknown activity"),
        (["--reminder", "x", "--at", "23/11/2026"], "--at"),
        (["--reminder", "x", "--at", "2020-01-01T10:00"], "in the past"),
        (["--reminder", "x", "--cron", "0 10 * *"], "expected 5 fields"),
        (["--reminder", "x", "--every", "60", "--tz", "Madrid"], "unknown time zone"),
    ],
)
def test_bad_add_is_one_line_and_stores_nothing(
    db: list[str], args: list[str], message: str
) -> None:
    code, _, error = _run("add", "--user", "ann", *args, *db)
    assert code != 0
    assert isinstance(error, AgendaError) and message in str(error)
    assert "\n" not in str(error)
    assert json.loads(_run("list", "--json", *db)[1]) == {"items": []}


def test_remove_unknown_id(db: list[str]) -> None:
    code, _, error = _run("remove", "42", *db)
    assert code != 0 and isinstance(error, AgendaNotFound)
    assert str(error) == "no agenda item 42"


class _Profiles:
    """Stands in for memory.ProfileStore (same constructor and ``get``) in this test."""

    closed = False

    def __init__(self, url: str) -> None:
        self.url = url

    def get(self, user_id: str) -> dict[str, str]:
        if user_id != "ann":
            raise KeyError(user_id)
        return {"id": user_id}

    def close(self) -> None:
        _Profiles.closed = True


def test_add_checks_the_user_against_the_profile_store(
    db: list[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    import memory

    monkeypatch.setattr(memory, "ProfileStore", _Profiles, raising=False)
    code, _, error = _run("add", "--user", "zoe", "--reminder", "x", "--every", "60", *db)
    assert code != 0 and str(error) == "unknown user 'zoe'"
    assert _run("add", "--user", "ann", "--reminder", "x", "--every", "60", *db)[0] == 0
    assert _Profiles.closed
