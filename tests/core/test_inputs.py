"""Validation of every input key and the freshness of inputs."""

from __future__ import annotations

import json

import pytest

from dms.inputs import MAX_PAYLOAD_BYTES, InputBoard, InputRejected, parse_input
from dms.kernel import keys
from dms.kernel.messages import ProfileParams, Request, Touch, UserPerception

VALID: dict[str, dict[str, object]] = {
    keys.PERCEPTION_USER: {"present": True, "user_id": "ann", "ready": True, "engagement": 0.5},
    keys.PERCEPTION_TOUCH: {"part": "right_shoulder", "kind": "tap"},
    keys.PERCEPTION_SPEECH: {"text": "let's play the quiz", "confidence": 0.9},
    keys.PERCEPTION_SCREEN: {"choice": "quiz"},
    keys.PARAMS_ROBOT: {"batterylevel": 80, "name": "mini"},
    keys.PARAMS_ENV: {"noise_db": 35.5, "light_lux": 200},
    keys.REQUEST: {"action": "start", "activity": "quiz", "by": "caregiver"},
    keys.ROBOT_FEEDBACK: {"id": "c1", "status": "done", "detail": None},
}

DEEP = ("[" * 100_000 + "]" * 100_000).encode()

MALFORMED: list[tuple[str, bytes, str]] = [
    (keys.PERCEPTION_USER, b"not json", "not JSON"),
    (keys.PERCEPTION_USER, b"[1, 2]", "expected a JSON object"),
    (keys.PERCEPTION_USER, b'{"present": "yes"}', "present"),
    (keys.PERCEPTION_USER, b'{"present": true, "engagement": 1.5}', "engagement"),
    (keys.PERCEPTION_USER, b'{"ready": true}', "present"),
    (keys.PERCEPTION_TOUCH, b'{"part": "knee", "kind": "tap"}', "part"),
    (keys.PERCEPTION_TOUCH, b'{"part": "head"}', "kind"),
    (keys.PERCEPTION_SPEECH, b'{"text": "hi", "confidence": -0.1}', "confidence"),
    (keys.PERCEPTION_SPEECH, b'{"text": 42, "confidence": 0.5}', "text"),
    (keys.PERCEPTION_SCREEN, b'{"choice": ""}', "choice"),
    (keys.PARAMS_ROBOT, b'{"batterylevel": [1]}', "batterylevel"),
    (keys.PARAMS_ENV, b'{"bad name": 1}', "bad name"),
    (keys.REQUEST, b'{"action": "start", "activity": "karaoke"}', "unknown activity"),
    (keys.REQUEST, b'{"action": "explode"}', "action"),
    (keys.ROBOT_FEEDBACK, b'{"id": "c1", "status": "exploded"}', "status"),
    (
        keys.PERCEPTION_SPEECH,
        json.dumps({"text": "a" * MAX_PAYLOAD_BYTES, "confidence": 1}).encode(),
        "exceeds",
    ),
    (keys.PERCEPTION_USER, b"\xff\xfe", "not JSON"),
    (keys.PARAMS_ENV, b'{"x": NaN}', ""),
]


@pytest.mark.parametrize("key", list(VALID))
def test_every_input_key_accepts_its_contract_payload(key: str) -> None:
    message = parse_input(key, json.dumps(VALID[key]).encode())
    assert message is not None


def test_unknown_fields_are_ignored() -> None:
    message = parse_input(keys.PERCEPTION_TOUCH, b'{"part": "head", "kind": "tap", "new": 1}')
    assert message == Touch(part="head", kind="tap")


@pytest.mark.parametrize(("key", "raw", "fragment"), MALFORMED)
def test_malformed_payloads_are_rejected_with_a_reason(key: str, raw: bytes, fragment: str) -> None:
    with pytest.raises(InputRejected) as caught:
        parse_input(key, raw)
    assert fragment in str(caught.value)
    assert "\n" not in str(caught.value)


@pytest.mark.parametrize("key", list(VALID))
def test_deeply_nested_json_is_rejected_on_every_key(key: str) -> None:
    nested = b'{"a": ' + b"[" * 5000 + b"]" * 5000 + b"}"
    with pytest.raises(InputRejected):
        parse_input(key, nested)
    with pytest.raises(InputRejected):
        parse_input(key, DEEP)


def test_a_state_input_goes_stale_then_recovers() -> None:
    board = InputBoard({keys.PERCEPTION_USER: 2.0})
    user = UserPerception(present=True, user_id="ann", ready=True)
    board.accept(keys.PERCEPTION_USER, user, received=10.0)
    assert board.take(11.0).status[keys.PERCEPTION_USER] == "ok"
    stale = board.take(12.5)
    assert stale.status[keys.PERCEPTION_USER] == "stale"
    assert keys.PERCEPTION_USER not in stale.values
    board.accept(keys.PERCEPTION_USER, user, received=13.0)
    assert board.take(13.1).values[keys.PERCEPTION_USER] == user


def test_a_missing_token_makes_the_input_missing_and_forgets_its_value() -> None:
    board = InputBoard()
    board.liveliness(keys.PERCEPTION_USER, True)
    assert board.take(0.0).status[keys.PERCEPTION_USER] == "missing"  # nothing received yet
    board.accept(keys.PERCEPTION_USER, UserPerception(present=True), received=1.0)
    assert board.take(1.0).status[keys.PERCEPTION_USER] == "ok"
    board.liveliness(keys.PERCEPTION_USER, False)
    snapshot = board.take(1.1)
    assert snapshot.status[keys.PERCEPTION_USER] == "missing"
    assert keys.PERCEPTION_USER not in snapshot.values


@pytest.mark.parametrize("key", [keys.PARAMS_ROBOT, keys.PARAMS_ENV])
def test_parameters_nobody_ever_sent_are_not_published_then_missing_once_gone(key: str) -> None:
    board = InputBoard()
    assert board.take(0.0).status[key] == "not_published"  # most robots never send them
    assert board.take(0.0).status[keys.PERCEPTION_USER] == "missing"  # not so a person
    board.accept(key, ProfileParams(values={"batterylevel": 80}), received=1.0)
    assert board.take(1.0).status[key] == "ok"
    board.liveliness(key, False)  # its module went away: now a fault
    assert board.take(1.1).status[key] == "missing"


def test_a_declared_parameters_module_that_has_not_spoken_yet_is_missing() -> None:
    board = InputBoard()
    board.liveliness(keys.PARAMS_ROBOT, True)
    assert board.take(0.0).status[keys.PARAMS_ROBOT] == "missing"


def test_events_are_handed_over_once_in_order() -> None:
    board = InputBoard()
    first = Request(action="start", activity="quiz")
    second = Touch(part="head", kind="caress")
    board.accept(keys.REQUEST, first, 1.0)
    board.accept(keys.PERCEPTION_TOUCH, second, 1.1)
    assert [e.message for e in board.take(1.2).events] == [first, second]
    assert board.take(1.3).events == ()


def test_params_merge_and_are_dropped_when_their_module_goes_away() -> None:
    board = InputBoard()
    board.accept(keys.PARAMS_ENV, ProfileParams(values={"noise_db": 30}), 1.0)
    board.accept(keys.PARAMS_ENV, ProfileParams(values={"light_lux": 5}), 1.1)
    assert board.take(2.0).env_params == {"noise_db": 30, "light_lux": 5}
    board.liveliness(keys.PARAMS_ENV, False)
    assert board.take(2.1).env_params == {}


def test_an_event_flood_is_bounded_and_counted() -> None:
    board = InputBoard()
    for i in range(1000):
        board.accept(keys.PERCEPTION_SCREEN, Touch(part="head", kind="tap"), float(i))
    assert len(board.take(1000.0).events) == 256
    assert board.counters.dropped_events == 1000 - 256


def test_params_keep_at_most_the_bound_of_names_dropping_the_one_set_longest_ago() -> None:
    board = InputBoard(max_param_names=3)
    board.accept(keys.PARAMS_ENV, ProfileParams(values={"a": 1, "b": 2, "c": 3}), 1.0)
    board.accept(keys.PARAMS_ENV, ProfileParams(values={"a": 10}), 1.1)  # a is newest now
    board.accept(keys.PARAMS_ENV, ProfileParams(values={"d": 4, "e": 5}), 1.2)
    assert board.take(2.0).env_params == {"a": 10, "d": 4, "e": 5}
    board.accept(keys.PARAMS_ROBOT, ProfileParams(values={"x": 1, "y": 2, "z": 3, "w": 4}), 2.1)
    assert board.take(2.2).robot_params == {"y": 2, "z": 3, "w": 4}
    due = {drops.key: (drops.count, drops.total) for drops in board.params_dropped.due(3.0)}
    assert due == {keys.PARAMS_ENV: (2, 2), keys.PARAMS_ROBOT: (1, 1)}


@pytest.mark.parametrize("key", [keys.PARAMS_ENV, keys.PARAMS_ROBOT])
def test_a_params_name_and_value_are_bounded_in_size(key: str) -> None:
    assert parse_input(key, json.dumps({"n" * 64: "v" * 1024}).encode())
    for payload, fragment in [
        ({"n" * 65: 1}, "n" * 65),
        ({"name": "v" * 1025}, "1024"),
        ({f"n{i}": i for i in range(257)}, "256"),
    ]:
        with pytest.raises(InputRejected, match=fragment):
            parse_input(key, json.dumps(payload).encode())


def test_an_unknown_activity_is_named_with_the_nearest_and_a_long_one_cut() -> None:
    with pytest.raises(InputRejected) as typo:
        parse_input(keys.REQUEST, b'{"action": "start", "activity": "jokez"}')
    assert str(typo.value) == "activity: unknown activity 'jokez'; did you mean jokes?"
    long = json.dumps({"action": "start", "activity": "jokes" * 2000}).encode()
    with pytest.raises(InputRejected) as cut:
        parse_input(keys.REQUEST, long)
    assert len(str(cut.value)) < 220 and "at most 40 characters" in str(cut.value)
