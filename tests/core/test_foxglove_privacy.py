"""What ``dms foxglove`` holds back by default, message by message (the bridge's
``redact``); tests/integration/test_foxglove.py runs it between a daemon and a client."""

from __future__ import annotations

from dms.foxglove_bridge import HIDDEN, _origins, loopback_origins, redact


def test_user_ids_and_free_text_are_hidden_at_any_depth_keeping_the_shape() -> None:
    state = {"tick": 3, "user": {"id": "ann", "ready": True}, "mode": "autonomous"}
    assert redact(state) == {"tick": 3, "user": {"id": HIDDEN, "ready": True}, "mode": "autonomous"}
    command = {"id": "c1", "channel": "screen", "action": "show"}
    command["args"] = {"text": "Ann, your pills", "choices": ["yes", "no"]}  # type: ignore[assignment]
    assert redact(command)["args"] == {"text": HIDDEN, "choices": []}
    decision = {"action": "start", "detail": "asked by speech: 'jokes'", "why": {"evidence": "x"}}
    assert redact(decision) == {"action": "start", "detail": HIDDEN, "why": {"evidence": HIDDEN}}
    assert redact({"present": True, "user_id": "ann"}) == {"present": True, "user_id": HIDDEN}
    assert redact({"detail": None}) == {"detail": None}


def test_origin_headers_are_read_case_blind() -> None:
    head = b"GET / HTTP/1.1\r\nHost: x\r\norigin: HTTPS://App.Foxglove.dev/\r\n\r\n"
    assert _origins(head) == ["https://app.foxglove.dev"]
    assert _origins(b"GET / HTTP/1.1\r\nHost: x\r\n\r\n") == []
    assert "http://localhost:8765" in loopback_origins(8765)
    assert "http://localhost:8766" not in loopback_origins(8765)
