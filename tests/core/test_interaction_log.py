"""The interaction log: a session's events from its ticks' decisions and inputs.

Offers open on ``ask`` decisions and menus, take the first spoken or tapped input with
its delay, close unanswered at the next decision, and are cut (not unanswered) by the
session's end; a newcomer's events wait for her key and are forgotten without one.
"""

from __future__ import annotations

from datetime import UTC, datetime, timedelta
from typing import Any

from dms.interactions import HELD_MAX, InteractionLog
from dms.kernel.messages import ChosenBy, Decision, ScreenChoice, Speech, Touch

T0 = datetime(2026, 12, 1, 10, 0, tzinfo=UTC)


def _at(seconds: float) -> datetime:
    return T0 + timedelta(seconds=seconds)


def _decision(
    action: str, activity: str | None, reason: str, by: ChosenBy | None = None
) -> Decision:
    return Decision.model_validate(
        {
            "tick": 1,
            "time": "2026-12-01T10:00:00Z",
            "action": action,
            "activity": activity,
            "manager": None,
            "reason": reason,
            "chosen_by": by,
        }
    )


class Written:
    def __init__(self) -> None:
        self.writes: list[tuple[str, str, list[dict[str, Any]]]] = []

    def __call__(self, user: str, key: str, events: list[dict[str, Any]]) -> None:
        self.writes.append((user, key, events))

    @property
    def events(self) -> list[dict[str, Any]]:
        return [event for _user, _key, events in self.writes for event in events]


def test_an_offer_takes_its_first_input_and_the_next_decision_closes_it() -> None:
    written = Written()
    log = InteractionLog(written, min_confidence=0.5)
    ask = _decision("ask", None, "general_question")
    log.observe(_at(0), "ann", [ask], [], "session-1")
    log.observe(_at(3), "ann", [], [Speech(text="ann", confidence=0.3)], "session-1")
    log.observe(_at(5), "ann", [], [Speech(text="Ann", confidence=0.9)], "session-1")
    menu = _decision("start", "menu", "user_choice", "user")
    log.observe(_at(6), "ann", [menu], [], "session-1")
    rating = _decision("ask", "quiz", "feedback")
    log.observe(
        _at(30),
        "ann",
        [_decision("complete", "menu", "completed", "user"), rating],
        [],
        "session-1",
    )
    log.observe(_at(33), "ann", [], [Touch(part="head", kind="caress")], "session-1")
    log.observe(
        _at(40), "ann", [_decision("start", "quiz", "preference", "robot")], [], "session-1"
    )
    log.observe(_at(41), None, [], [], None)
    shown = [
        (e["seq"], e["event"], e.get("offer"), e.get("offer_kind"), e.get("delay_s"))
        for e in written.events
    ]
    assert shown == [
        (0, "arrived", None, None, None),
        (1, "offered", 1, "question", None),
        (2, "input", 1, "question", 3.0),
        (3, "input", 1, "question", 5.0),
        (4, "started", None, None, None),
        (5, "offered", 2, "menu", None),
        (6, "unanswered", 2, "menu", None),
        (7, "completed", None, None, None),
        (8, "offered", 3, "rating", None),
        (9, "input", None, None, None),
        (10, "unanswered", 3, "rating", None),
        (11, "started", None, None, None),
        (12, "left", None, None, None),
    ]
    assert [e.get("understood") for e in written.events[2:4]] == [False, True]
    assert written.events[9]["channel"] == "touch"
    assert {key for _user, key, _events in written.writes} == {"session-1"}


def test_the_sessions_end_cuts_an_open_offer_without_calling_it_unanswered() -> None:
    written = Written()
    log = InteractionLog(written, min_confidence=0.5)
    log.observe(_at(0), "ann", [_decision("start", "menu", "user_choice", "user")], [], "k")
    gone = _decision("cancel", "menu", "user_left")
    log.observe(_at(9), None, [gone], [ScreenChoice(choice="quiz")], None)
    events = [(e["event"], e.get("by"), e.get("detail")) for e in written.events]
    assert events[-3:] == [
        ("input", None, None),
        ("cancelled", "robot", "user_left"),
        ("left", None, "user_left"),
    ]
    assert written.events[-3]["delay_s"] == 9.0
    assert not [e for e in written.events if e["event"] == "unanswered"]


def test_a_newcomers_events_wait_for_her_key_and_go_with_her_if_she_never_gets_one() -> None:
    written = Written()
    log = InteractionLog(written, min_confidence=0.5)
    log.observe(_at(0), "newcomer", [_decision("ask", None, "general_question")], [], None)
    log.observe(_at(2), "newcomer", [], [Speech(text="Eve", confidence=0.9)], None)
    assert written.writes == []
    log.observe(_at(4), "newcomer", [], [], "session-eve")  # stored: her events go, in order
    assert [e["seq"] for e in written.events] == [0, 1, 2]
    log.observe(_at(5), "ghost", [], [], None)  # the newcomer left, a ghost arrived
    for second in range(HELD_MAX + 10):
        log.observe(_at(6 + second), "ghost", [], [Touch(part="head", kind="tap")], None)
    log.observe(_at(9999), None, [], [], None)
    assert {user for user, _key, _events in written.writes} == {"newcomer"}
