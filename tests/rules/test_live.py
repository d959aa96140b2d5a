"""LiveRules for the daemon, and the example decision-point components."""

from __future__ import annotations

import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from dms.rules import LiveRules, RuleResult, RulesError, load_rules

from .conftest import EXAMPLES

Write = Callable[..., Path]


def test_evaluate_is_none_when_the_component_is_not_defined(write: Write) -> None:
    live = LiveRules([write('component ChooseMode [ activate "hybrid" ]')])
    assert live.evaluate("ChooseMode", {}) == RuleResult(("hybrid",))
    assert live.evaluate("VoiceSettings", {}) is None
    assert live.current.defines("ChooseMode")
    assert not live.current.defines("VoiceSettings")


def test_reload_swaps_in_valid_rules(write: Write) -> None:
    path = write('component ChooseMode [ activate "hybrid" ]')
    live = LiveRules([path])
    path.write_text('component ChooseMode [ activate "autonomous" ]', encoding="utf-8")
    assert live.reload() == []
    assert live.evaluate("ChooseMode", {}) == RuleResult(("autonomous",))


def test_reload_keeps_the_old_rules_when_new_ones_do_not_verify(write: Write) -> None:
    path = write('component ChooseMode [ activate "hybrid" ]')
    live = LiveRules([path])
    old = live.current
    path.write_text('component ChooseMode [ if nope then activate "x" ]', encoding="utf-8")
    problems = live.reload()
    assert [str(p) for p in problems] == [f"{path}:1:27: unknown name 'nope'"]
    assert live.current is old
    path.unlink()
    assert [p.message for p in live.reload()] == ["cannot read: No such file or directory"]
    assert live.evaluate("ChooseMode", {}) == RuleResult(("hybrid",))


def test_invalid_rules_at_start_raise(write: Write) -> None:
    with pytest.raises(RulesError, match="syntax error"):
        LiveRules([write("component [")])


def test_evaluations_during_reloads_see_whole_rule_sets(write: Write) -> None:
    first = 'component C [ activate "a" activate "b" ]'
    second = 'component C [ activate "c" activate "d" ]'
    path = write(first)
    live = LiveRules([path])
    seen: set[tuple[str, ...]] = set()
    lock = threading.Lock()
    stop = threading.Event()

    def evaluate() -> None:
        while not stop.is_set():
            result = live.evaluate("C", {})
            assert result is not None
            with lock:
                seen.add(result.activate)

    threads = [threading.Thread(target=evaluate) for _ in range(3)]
    for thread in threads:
        thread.start()
    try:
        for index in range(40):
            path.write_text(second if index % 2 == 0 else first, encoding="utf-8")
            assert live.reload() == []
    finally:
        stop.set()
        for thread in threads:
            thread.join()
    assert seen <= {("a", "b"), ("c", "d")}
    assert seen


# --------------------------------------------------------- the decision points

DECISIONS = EXAMPLES / "decisions.dmsl"


def decide(component: str, **profiles: dict[str, Any]) -> tuple[str, ...]:
    return load_rules([DECISIONS]).evaluate(component, profiles).activate


def test_choose_mode() -> None:
    assert decide("ChooseMode", user={"proactivity": "high"}) == ("user_choice",)
    assert decide("ChooseMode", user={"proactivity": "low"}) == ("autonomous",)
    assert decide("ChooseMode", user={"proactivity": "moderate", "age": 95}) == ("autonomous",)
    assert decide("ChooseMode", user={}) == ("hybrid",)


def test_choose_entertainment() -> None:
    calm = {"noise_db": 40}
    assert decide("ChooseEntertainment", robot={"batterylevel": 10}) == ("jokes",)
    full = {"batterylevel": 90}
    assert decide("ChooseEntertainment", robot=full, env={"time": 9, **calm}) == ("news",)
    assert decide("ChooseEntertainment", robot=full, env={"time": 20, **calm}) == ("multimedia",)
    assert decide("ChooseEntertainment", robot=full, env={"time": 20, "noise_db": 80}) == ("quiz",)
    young = {"age": 70, "likes": ["dance", "quiz"]}
    assert decide("ChooseEntertainment", robot=full, env={"time": 15}, user=young) == ("dance",)


def test_allow_interruption() -> None:
    assert decide("AllowInterruption", robot={"currenttask": "presentation"}) == ("deny",)
    assert decide("AllowInterruption", robot={"currenttask": "quiz"}) == ("allow",)
    assert decide("AllowInterruption") == ("allow",)


def test_voice_settings() -> None:
    assert decide("VoiceSettings", user={"hearing": False, "age": 85}, env={"time": 12}) == (
        "volume:85",
        "rate:130",
    )
    assert decide("VoiceSettings", user={"hearing": True, "age": 60}, env={"time": 23}) == (
        "volume:40",
        "rate:160",
    )
    quiet_day = {"time": 12, "noise_db": 30}
    assert decide("VoiceSettings", user={"hearing": True, "age": 60}, env=quiet_day) == (
        "volume:60",
        "rate:160",
    )
