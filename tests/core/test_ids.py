"""The one identifier rule: every id that crosses the bus or a store."""

from __future__ import annotations

import json
import re

import pytest
from hypothesis import given
from hypothesis import strategies as st

from dms.inputs import InputRejected, parse_input
from dms.kernel.ids import MAX_ID_LENGTH, InvalidIdentifier, check_identifier, printable

HOSTILE = [
    ("", "empty"),
    ("   ", "empty"),
    ("\t\n", "empty"),
    ("a\x00b", "U+0000"),
    ("ann\nsmith", "U+000A"),
    ("ann\rforged", "U+000D"),
    ("\u202eevil", "U+202E"),  # right-to-left override
    ("zero\u200bwidth", "U+200B"),
    ("line\u2028sep", "U+2028"),
    ("a/b", "reserve"),
    ("users*", "reserve"),
    ("@ann", "verbatim"),
    ("x" * (MAX_ID_LENGTH + 1), "longer"),
    ("\ud800", "U+D800"),  # a lone surrogate
]


@pytest.mark.parametrize(("value", "fault"), HOSTILE)
def test_hostile_ids_are_refused_naming_the_fault(value: str, fault: str) -> None:
    with pytest.raises(InvalidIdentifier, match=re.escape(fault)) as error:
        check_identifier(value, "user_id")
    assert str(error.value).startswith("user_id: ")
    assert "\n" not in str(error.value)


def test_ids_are_trimmed_and_may_hold_spaces_and_any_script() -> None:
    assert check_identifier("  Ann Smith ") == "Ann Smith"
    assert check_identifier("José-María_3.b") == "José-María_3.b"
    assert check_identifier("ann@home") == "ann@home"
    assert check_identifier("张伟") == "张伟"
    assert check_identifier("x" * MAX_ID_LENGTH) == "x" * MAX_ID_LENGTH


def test_non_strings_are_refused() -> None:
    with pytest.raises(InvalidIdentifier, match="must be a string"):
        check_identifier(7)


@pytest.mark.parametrize(("value", "fault"), HOSTILE[:-1])
def test_the_bus_refuses_hostile_user_ids(value: str, fault: str) -> None:
    raw = json.dumps({"present": True, "ready": True, "user_id": value})
    with pytest.raises(InputRejected, match=f"user_id: .*{re.escape(fault)}"):
        parse_input("perception/user", raw.encode())


def test_the_bus_refuses_a_forged_line_in_request_by() -> None:
    with pytest.raises(InputRejected, match=r"by: .*U\+000A"):
        parse_input("request", b'{"action": "cancel", "by": "app\\n12:00 start quiz"}')


@given(st.text(max_size=300))
def test_check_is_total_and_its_result_obeys_the_rule(value: str) -> None:
    """Any string is either refused with InvalidIdentifier or comes back valid and stable."""
    try:
        trimmed = check_identifier(value)
    except InvalidIdentifier:
        return
    assert trimmed == trimmed.strip() and 0 < len(trimmed) <= MAX_ID_LENGTH
    assert check_identifier(trimmed) == trimmed


@given(st.text(max_size=500))
def test_printable_never_holds_a_line_break(text: str) -> None:
    shown = printable(text)
    assert "\n" not in shown and "\r" not in shown and "\x00" not in shown
    assert "\u2028" not in shown
