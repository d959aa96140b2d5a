"""The face's side of the bus: what the daemon says feeds :class:`FaceFeed`, what the
person does goes out as perception.

It subscribes to ``robot/command``, ``dms/decision`` and ``dms/state`` of one robot and
watches its ``alive/dms``. It acts as that robot's perception module for the person in
front of the page: it declares ``alive/perception/user`` and publishes
``perception/user`` every :data:`PRESENCE_EVERY_S` (so the daemon's sessions start and
end as with a camera), and one ``perception/screen``, ``perception/speech`` or
``perception/touch`` per tap, typed answer, utterance or touch. Each message is checked
against the contract's model before it goes out. The people the daemon knows come from
its ``users/*`` queryable when the daemon serves it (``[privacy] serve_profiles``).
"""

from __future__ import annotations

import json
import logging
import queue
import threading
import time
from contextlib import suppress
from typing import Any

from dms.bus import ZenohClient
from dms.face.feed import MAX_PEOPLE, FaceFeed
from dms.kernel import keys
from dms.kernel.ids import check_identifier
from dms.kernel.messages import ScreenChoice, Speech, Touch, UserPerception

log = logging.getLogger(__name__)

PRESENCE_EVERY_S = 1.0
"""How often ``perception/user`` is said again: well inside the daemon's 5 s staleness."""
MAX_READ_BYTES = 256 * 1024
"""A payload over this is not parsed: no command of the daemon's comes near it."""
QUERY_TIMEOUT_S = 3.0
LANGUAGE_TAGS = {
    "english": "en",
    "spanish": "es",
    "french": "fr",
    "german": "de",
    "italian": "it",
    "portuguese": "pt",
    "catalan": "ca",
    "basque": "eu",
    "galician": "gl",
    "greek": "el",
    "dutch": "nl",
    "chinese": "zh",
    "arabic": "ar",
    "russian": "ru",
}
"""The profile's language (as the daemon's question stores it) as a BCP 47 tag for the
browser's voices."""


class FaceLink:
    """One robot's daemon, seen and spoken to by the face page."""

    def __init__(self, client: ZenohClient, feed: FaceFeed) -> None:
        self.client = client
        self.feed = feed
        self._lock = threading.Lock()
        self._present = False
        self._user: str | None = None
        self._consented: set[str] = set()
        """Ids whose consent this page took since it started (the daemon may not say
        whom it knows)."""
        self._known: set[str] = set()
        self._stop = threading.Event()
        self._jobs: queue.Queue[str | None] = queue.Queue(maxsize=4)
        self._threads = [
            threading.Thread(target=self._say_presence, name="dms-face-presence", daemon=True),
            threading.Thread(target=self._work, name="dms-face-queries", daemon=True),
        ]

    def start(self) -> None:
        handlers = {
            keys.ROBOT_COMMAND: self.feed.on_command,
            keys.DMS_DECISION: self.feed.on_decision,
            keys.DMS_STATE: self.feed.on_state,
        }
        for key, handler in handlers.items():
            self.client.subscribe_raw(self.client.key(key), _json(handler))
        self.client.watch_tokens(
            self.client.key(keys.ALIVE_DMS), lambda _key, alive: self._on_alive(alive)
        )
        self.client.declare_token(keys.ALIVE_PREFIX + keys.PERCEPTION_USER)
        for thread in self._threads:
            thread.start()
        self.refresh_people()

    def close(self) -> None:
        """Say nobody is here (the daemon ends the session now, not when the token
        goes), then stop."""
        with self._lock:
            present = self._present
            self._present, self._user = False, None
        if present:
            self._publish_presence()
        self._stop.set()
        self._jobs.put(None)
        for thread in self._threads:
            thread.join(timeout=2 * QUERY_TIMEOUT_S)
        self.client.close()

    # ------------------------------------------------------------------ the person

    def screen(self, choice: str) -> None:
        """A tap on the tablet. Raises ValueError (pydantic's) for a malformed one."""
        message = ScreenChoice(choice=choice)
        self.client.publish(keys.PERCEPTION_SCREEN, message.model_dump())

    def speech(self, text: str, confidence: float) -> None:
        """An utterance: typed (confidence 1) or recognised from the microphone."""
        message = Speech(text=text, confidence=confidence)
        self.client.publish(keys.PERCEPTION_SPEECH, message.model_dump())

    def touch(self, part: str, kind: str) -> None:
        message = Touch.model_validate({"part": part, "kind": kind})
        self.client.publish(keys.PERCEPTION_TOUCH, message.model_dump())

    def needs_consent(self, user_id: str) -> bool:
        """Whether ``user_id`` is someone new to this robot: neither a profile the daemon
        listed nor someone who consented on this page."""
        with self._lock:
            return user_id not in self._known and user_id not in self._consented

    def arrive(self, user_id: str, consent: bool) -> str:
        """``user_id`` sits in front of the robot. Raises ValueError for an id the daemon
        would refuse, and PermissionError for someone new without consent."""
        user_id = check_identifier(user_id, "user id")
        if consent:
            with self._lock:
                self._consented.add(user_id)
        elif self.needs_consent(user_id):
            raise PermissionError(
                f"{user_id} is new here: their consent is asked before a session is recorded"
            )
        with self._lock:
            self._present, self._user = True, user_id
        self._publish_presence()
        self.feed.set_presence(True, user_id)
        return user_id

    def leave(self) -> None:
        with self._lock:
            self._present, self._user = False, None
        self._publish_presence()
        self.feed.set_presence(False, None)
        self.refresh_people()  # a new person's profile is stored once the session ends

    def _publish_presence(self) -> None:
        with self._lock:
            present, user = self._present, self._user
        message = UserPerception(present=present, user_id=user, ready=present)
        self.client.publish(keys.PERCEPTION_USER, message.model_dump(exclude_none=True))

    def _say_presence(self) -> None:
        """``perception/user`` on a fixed period, as a camera would say it."""
        deadline = time.monotonic()
        while not self._stop.is_set():
            try:
                self._publish_presence()
            except Exception:  # the session is closing under us; the loop ends next
                log.debug("perception/user not published", exc_info=True)
            deadline += PRESENCE_EVERY_S
            self._stop.wait(max(0.0, deadline - time.monotonic()))

    # ------------------------------------------------------------------ the daemon

    def _on_alive(self, alive: bool) -> None:
        self.feed.on_alive(alive)
        if alive:
            self.refresh_people()

    def refresh_people(self) -> None:
        """Ask the daemon again whom it knows (in the worker; never from a callback)."""
        with suppress(queue.Full):  # enough asks are queued already
            self._jobs.put_nowait("people")

    def _work(self) -> None:
        while True:
            job = self._jobs.get()
            if job is None or self._stop.is_set():
                return
            try:
                self._read_people()
            except Exception:  # one failed query must not end the worker
                log.exception("users/* query")

    def _read_people(self) -> None:
        replies = self.client.query(keys.USERS_PREFIX + "*", timeout_s=QUERY_TIMEOUT_S)
        if not replies:
            self.feed.set_people([], "the daemon did not answer")
            return
        ok, body = replies[0]
        ids = body.get("users") if ok and isinstance(body, dict) else None
        if not isinstance(ids, list):
            reason = body.get("error") if isinstance(body, dict) else None
            self.feed.set_people([], str(reason or "the daemon's answer is not understood"))
            return
        people = [self._person(str(user)) for user in ids[:MAX_PEOPLE]]
        with self._lock:
            self._known = {person["id"] for person in people}
        people.sort(key=lambda person: str(person["name"]).lower())
        self.feed.set_people(people, "")

    def _person(self, user_id: str) -> dict[str, Any]:
        """The id, the name the daemon asked for and the language as a BCP 47 tag."""
        person: dict[str, Any] = {"id": user_id, "name": user_id, "language": None}
        replies = self.client.query(keys.USERS_PREFIX + user_id, timeout_s=QUERY_TIMEOUT_S)
        if replies and replies[0][0] and isinstance(replies[0][1], dict):
            profile = replies[0][1].get("profile")
            if isinstance(profile, dict):
                if isinstance(profile.get("name"), str) and profile["name"].strip():
                    person["name"] = profile["name"].strip()[:200]
                language = str(profile.get("language") or "").strip().lower()
                person["language"] = LANGUAGE_TAGS.get(language)
        return person


def _json(handler: Any) -> Any:
    def on_sample(_key: str, raw: bytes) -> None:
        if len(raw) > MAX_READ_BYTES:
            return
        try:
            payload = json.loads(raw)
        except (ValueError, RecursionError):
            return  # not a daemon's: the daemon publishes plain JSON only
        handler(payload)

    return on_sample
