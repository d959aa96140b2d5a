"""What the face page shows, kept from the daemon's messages; no Zenoh, no web.

The bus side calls the ``on_*`` methods from Zenoh's threads; each page attaches a
listener, gets a snapshot (so a page opened mid-session shows the screen, the cheeks and
the last captions at once) and then every change as an event:

- ``say`` ``{id, text, rate_wpm?, volume?}``: an utterance (the caption, and the voice);
- ``interrupt`` ``{target}``: an utterance cut short (a robot reached over Zenoh only);
- ``screen`` ``{id, text, choices, face?, image?}``: what the tablet shows;
- ``led`` ``{color, pattern}``: the cheeks; ``gaze`` ``{neck, head, hip}``: where it looks;
- ``motion`` ``{name}``: a gesture (the face bobs);
- ``decision``: the daemon's decision as published; ``state`` ``{user, activity, state}``;
- ``alive`` ``{alive}``: the daemon's token; ``presence``, ``people``, ``heard``: the
  person's side (who the page says is here, the known people, what the microphone heard).

Every string and list taken from the bus is cut to a bound: the page never receives more
than :data:`MAX_TEXT` characters of one text or :data:`MAX_CHOICES` choices.
"""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Callable
from typing import Any

Listener = Callable[[str, dict[str, Any]], None]
"""Called with an event's name and data; an empty name tells the page to reconnect."""

CAPTIONS_KEPT = 20
"""Utterances a page opened later gets as its captions."""
MAX_TEXT = 1000
MAX_CHOICES = 40
MAX_CHOICE_TEXT = 200
MAX_PEOPLE = 100
LISTENERS_MAX = 32
"""Pages open at once; one more is refused (a tablet and a laptop or two is the use)."""
GAZE_JOINTS = ("neck", "head", "hip")


def _text(value: Any, limit: int = MAX_TEXT) -> str:
    return value[:limit] if isinstance(value, str) else ""


def _mapping(value: Any) -> dict[str, Any]:
    return value if isinstance(value, dict) else {}


def _number(value: Any) -> float | None:
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    number = float(value)
    return number if -10.0 <= number <= 1000.0 else None


class FaceFeed:
    """The face's state and the pages listening to it (thread-safe)."""

    def __init__(self, robot: str, voice: str | None = None, language: str = "en") -> None:
        """``voice``: None when push-to-talk works, else why not (shown on the page)."""
        self.robot = robot
        self.language = language
        self.voice_missing = voice
        self._lock = threading.Lock()
        self._listeners: list[Listener] = []
        self._said: deque[dict[str, Any]] = deque(maxlen=CAPTIONS_KEPT)
        self._screen: dict[str, Any] | None = None
        self._led: dict[str, Any] | None = None
        self._gaze: dict[str, float] = {}
        self._state: dict[str, Any] = {"user": None, "activity": None, "state": None}
        self._decision: dict[str, Any] | None = None
        self._alive = False
        self._presence: dict[str, Any] = {"present": False, "user_id": None}
        self._people: dict[str, Any] = {"people": [], "note": "asking the daemon"}

    # ------------------------------------------------------------------ pages

    def attach(self, listener: Listener) -> dict[str, Any] | None:
        """Add a page; its first data, or None when too many pages are open."""
        with self._lock:
            if len(self._listeners) >= LISTENERS_MAX:
                return None
            self._listeners.append(listener)
            return self._snapshot()

    def detach(self, listener: Listener) -> None:
        with self._lock:
            if listener in self._listeners:
                self._listeners.remove(listener)

    def end_streams(self) -> None:
        """The server stops: every page's stream ends now."""
        self._emit("", {})

    def snapshot(self) -> dict[str, Any]:
        with self._lock:
            return self._snapshot()

    def _snapshot(self) -> dict[str, Any]:
        return {
            "robot": self.robot,
            "language": self.language,
            "voice_missing": self.voice_missing,
            "alive": self._alive,
            "said": list(self._said),
            "screen": self._screen,
            "led": self._led,
            "gaze": dict(self._gaze),
            "state": dict(self._state),
            "decision": self._decision,
            "presence": dict(self._presence),
            "people": self._people,
        }

    def _emit(self, name: str, data: dict[str, Any]) -> None:
        with self._lock:
            listeners = list(self._listeners)
        for listener in listeners:
            listener(name, data)

    # ------------------------------------------------------------------ the daemon

    def on_command(self, payload: Any) -> None:
        """One ``robot/command``: kept and passed on by channel; others are ignored."""
        if not isinstance(payload, dict):
            return
        channel, action = payload.get("channel"), payload.get("action")
        args = _mapping(payload.get("args"))
        ident = _text(payload.get("id"), 200)
        if action == "interrupt":
            self._emit("interrupt", {"target": _text(args.get("target"), 200)})
        elif channel == "speech" and action == "say":
            self._on_say(ident, args)
        elif channel == "screen" and action == "show":
            self._on_screen(ident, args)
        elif channel == "led":
            led = {"color": _text(args.get("color"), 40), "pattern": _text(args.get("pattern"), 40)}
            with self._lock:
                self._led = led
            self._emit("led", led)
        elif channel == "aim":
            self._on_aim(args)
        elif channel == "motion" and action == "gesture":
            self._emit("motion", {"name": _text(args.get("name"), 60)})

    def _on_say(self, ident: str, args: dict[str, Any]) -> None:
        said: dict[str, Any] = {"id": ident, "text": _text(args.get("text"))}
        for name in ("rate_wpm", "volume"):
            number = _number(args.get(name))
            if number is not None:
                said[name] = number
        if not said["text"].strip():
            return
        with self._lock:
            self._said.append(said)
        self._emit("say", said)

    def _on_screen(self, ident: str, args: dict[str, Any]) -> None:
        raw = args.get("choices")
        choices = [
            _text(str(choice), MAX_CHOICE_TEXT)  # a number is offered as its text
            for choice in (raw if isinstance(raw, list) else [])[:MAX_CHOICES]
            if isinstance(choice, str | int | float) and not isinstance(choice, bool)
        ]
        screen: dict[str, Any] = {"id": ident, "text": _text(args.get("text")), "choices": choices}
        for name in ("face", "image"):
            if isinstance(args.get(name), str):
                screen[name] = _text(args[name], 200)
        with self._lock:
            self._screen = screen
        self._emit("screen", screen)

    def _on_aim(self, args: dict[str, Any]) -> None:
        joints = _mapping(args.get("joints"))
        gaze = {
            name: value
            for name in GAZE_JOINTS
            if (value := _number(joints.get(name))) is not None and abs(value) <= 6.3
        }
        if args.get("frame", "") is None and not gaze:
            gaze = dict.fromkeys(GAZE_JOINTS, 0.0)  # back to neutral
        if not gaze:
            return
        with self._lock:
            self._gaze.update(gaze)
            now = dict(self._gaze)
        self._emit("gaze", now)

    def on_decision(self, payload: Any) -> None:
        if not isinstance(payload, dict):
            return
        decision = {
            name: _text(payload.get(name), 400)
            for name in ("action", "activity", "reason", "chosen_by", "detail", "time")
        }
        with self._lock:
            self._decision = decision
        self._emit("decision", decision)

    def on_state(self, payload: Any) -> None:
        """``dms/state``: passed on only when the user or the activity changed."""
        if not isinstance(payload, dict):
            return
        user = payload.get("user")
        activity = payload.get("activity")
        state = {
            "user": _text(user.get("id"), 200) if isinstance(user, dict) else None,
            "activity": _text(activity.get("name"), 60) if isinstance(activity, dict) else None,
            "status": _text(activity.get("status"), 20) if isinstance(activity, dict) else None,
        }
        with self._lock:
            changed = state != self._state
            self._state = state
        if changed:
            self._emit("state", state)

    def on_alive(self, alive: bool) -> None:
        with self._lock:
            changed = alive != self._alive
            self._alive = alive
        if changed:
            self._emit("alive", {"alive": alive})

    # ------------------------------------------------------------------ the person

    def set_presence(self, present: bool, user_id: str | None) -> None:
        presence = {"present": present, "user_id": user_id if present else None}
        with self._lock:
            self._presence = presence
        self._emit("presence", presence)

    def set_people(self, people: list[dict[str, Any]], note: str) -> None:
        """The people the daemon knows (``users/*``), or why none are listed."""
        data = {"people": people[:MAX_PEOPLE], "note": note}
        with self._lock:
            self._people = data
        self._emit("people", data)

    def heard(self, text: str, confidence: float) -> None:
        self._emit("heard", {"text": text[:MAX_TEXT], "confidence": confidence})
