"""The per-session Table 4 accounting (``dms.kernel.session_metrics``), and its storage."""

from __future__ import annotations

from collections.abc import Sequence
from datetime import UTC, datetime, timedelta
from pathlib import Path

import pytest

from dms.kernel.expression import CommandHandle, CommandStatus, Priority
from dms.kernel.messages import Decision
from dms.kernel.session_metrics import METRIC_KEYS, SessionAccount
from memory import ProfileStore
from memory.errors import ProfileError

T0 = datetime(2026, 11, 24, 9, 0, tzinfo=UTC)


def at(seconds: float) -> datetime:
    return T0 + timedelta(seconds=seconds)


def decision(
    action: str,
    activity: str | None,
    reason: str,
    chosen_by: str | None = None,
    detail: str | None = None,
) -> Decision:
    return Decision.model_validate(
        {
            "tick": 1,
            "time": T0.isoformat(),
            "action": action,
            "activity": activity,
            "manager": None,
            "reason": reason,
            "chosen_by": chosen_by,
            "detail": detail,
        }
    )


def handle(source: str, sent: float, ident: str) -> CommandHandle:
    return CommandHandle(
        source,
        "speech",
        "say",
        {},
        Priority.NORMAL,
        status=CommandStatus.SENT,
        command_id=ident,
        sent_at=at(sent),
    )


class Robot:
    """The arbiter's pending commands, by source, as the test sets them."""

    def __init__(self) -> None:
        self.by_source: dict[str, list[CommandHandle]] = {}

    def pending(self, source: str) -> Sequence[CommandHandle]:
        return self.by_source.get(source, [])


def test_a_session_counts_as_table_4_does() -> None:
    robot = Robot()
    account = SessionAccount(T0, misheard=4, unanswered=1)
    account.on_decision(decision("ask", None, "general_question"), at(0))
    # The robot picks jokes; its first command is sent at once and heard started 3.5 s later.
    account.on_decision(decision("start", "jokes", "preference", "robot"), at(10))
    first = handle("activity:jokes", 10, "cmd-9")
    later = handle("activity:jokes", 10, "cmd-10")
    robot.by_source["activity:jokes"] = [later, first]
    account.on_tick(at(10), robot.pending)
    account.on_tick(at(12), robot.pending)
    first.started_at = at(13.5)
    account.on_tick(at(13.5), robot.pending)
    account.on_decision(decision("complete", "jokes", "completed", "robot"), at(110))
    # A menu (not counted), then the user's pick, cancelled by a shoulder touch.
    account.on_decision(decision("start", "menu", "user_choice", "user"), at(115))
    account.on_decision(decision("complete", "menu", "completed", "user"), at(125))
    account.on_decision(decision("start", "quiz", "user_choice", "user"), at(130))
    account.on_decision(decision("cancel", "quiz", "confirm_cancel", "user"), at(150))
    # An activity that never loads, one that fails, one the user leaves (not a cancel).
    account.on_decision(
        decision("fail", "news", "activity_error", "robot", "not loaded: x"), at(151)
    )
    account.on_decision(decision("start", "music", "preference", "robot"), at(160))
    account.on_decision(decision("fail", "music", "activity_error", "robot", "boom"), at(170))
    account.on_decision(decision("start", "dance", "user_request", "user"), at(180))
    account.on_decision(decision("cancel", "dance", "user_left", "user"), at(200))
    result = account.result(at(200), misheard=6, unanswered=1)

    assert list(result) == list(METRIC_KEYS)
    assert result == {
        "duration_s": 200.0,
        "questions_per_session": 1,
        "activities_per_session": 4,
        "activity_load_time_s": 3.5,  # only jokes was heard started
        "activity_time_s": round((100 + 20 + 10 + 20) / 4, 3),
        "change_time_s": round((130 - 110 + 160 - 150 + 180 - 170) / 3, 3),
        "robot_decisions_per_session": 2,
        "user_selections_per_session": 2,
        "cancels_per_session": 1,
        "activity_not_loaded": 1,
        "speech_recognition_errors": 2,
        "user_not_answering": 0,
        "other": 1,
    }


def test_a_first_command_that_never_starts_leaves_no_load_time() -> None:
    robot = Robot()
    account = SessionAccount(T0)
    account.on_decision(decision("start", "quiz", "preference", "robot"), at(1))
    first = handle("activity:quiz", 1, "cmd-1")
    robot.by_source["activity:quiz"] = [first]
    account.on_tick(at(1), robot.pending)
    first.status = CommandStatus.TIMED_OUT
    account.on_tick(at(11), robot.pending)
    first.started_at = at(12)  # too late: the account no longer waits for it
    account.on_tick(at(12), robot.pending)
    assert account.result(at(20))["activity_load_time_s"] is None
    # A session with no activity has no times to average.
    empty = SessionAccount(T0).result(at(5))
    assert empty["activity_time_s"] is None and empty["change_time_s"] is None
    assert empty["activities_per_session"] == 0


def test_the_store_keeps_metrics_with_the_session_and_reads_them_back(tmp_path: Path) -> None:
    store = ProfileStore(f"sqlite:///{tmp_path / 'dms.db'}")
    try:
        store.get_or_create("ann", T0)
        first = store.start_session("ann", T0)
        store.end_session(first, at(60), metrics={"cancels_per_session": 1, "change_time_s": None})
        second = store.start_session("ann", at(3600))
        assert [s["session"] for s in store.sessions()] == [first, second]
        assert store.sessions()[0]["metrics"] == {"cancels_per_session": 1, "change_time_s": None}
        assert store.sessions()[1]["metrics"] is None and store.sessions()[1]["ended"] is None
        assert [s["session"] for s in store.sessions(at(60))] == [second]
        with pytest.raises(ProfileError, match="metrics"):
            store.end_session(second, at(3700), metrics={"x": float("nan")})
        with pytest.raises(ProfileError, match="metrics"):
            store.end_session(second, at(3700), metrics={"x": "text"})
        assert store.export("ann")["sessions"][0]["metrics"]["cancels_per_session"] == 1
        store.erase("ann")
        assert store.sessions() == []
    finally:
        store.close()
