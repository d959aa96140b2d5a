"""The interaction log: each session's events as a participant model needs them.

When is this called? At the end of every tick (and of the shutdown), with the tick's
time, the session's user, the tick's decisions, the inputs it handled and the session's
key. What does it do? It turns them into the events of :mod:`memory.interactions`:
the session's arrival and departure, each offer (a menu, a question, a rating,
"continue or stop?"), each input with its channel, the recogniser's confidence and its
delay since the open offer, the offers nobody answered, and the decisions about the
user's activities with who chose or stopped them. It reads only what the tick
published (``dms/decision``) and what perception sent: nothing of the controller's
inside, so the controller's refactoring leaves it be.

The events of a tick go to ``write`` at once (the daemon's background writer: the tick
never waits; the simulator writes each session's at its end). A newcomer's session has no
key until she is stored: her events wait here (at most :data:`HELD_MAX`), and are
forgotten with her if she never is.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any

from dms.kernel.messages import Decision, Request, ScreenChoice, Speech, Touch
from memory.interactions import MAX_EVENTS

log = logging.getLogger(__name__)

Event = dict[str, Any]
"""One event, the values of :func:`memory.interactions.check_event`."""
Write = Callable[[str, str, list[Event]], None]
"""Stores (user id, session key, events) off the tick."""

HELD_MAX = 2000
"""Events held for a session not stored yet; later ones are dropped (with a warning)."""
ASKS: dict[str, str] = {"general_question": "question", "feedback": "rating"}
"""``ask`` decisions by reason, and the offer they make (others: ``confirm``)."""
ACTIVITY_EVENTS: dict[str, str] = {
    "start": "started",
    "complete": "completed",
    "cancel": "cancelled",
    "fail": "failed",
    "pause": "paused",
    "resume": "resumed",
}
USER_STOPS = frozenset({"confirm_cancel", "user_request"})
SESSION_ENDS = frozenset({"user_left", "input_missing", "shutdown"})
"""Reasons of the decisions a session's end makes: an offer they close was cut, not
left unanswered."""
"""Cancel reasons that are the user's own (the paper's cancels)."""
_TEXT = 200


@dataclass
class _Offer:
    number: int
    kind: str
    at: datetime
    activity: str | None
    answered: bool = False


@dataclass
class _Session:
    user_id: str
    key: str | None
    started: datetime
    seq: int = 0
    offers: int = 0
    offer: _Offer | None = None
    waiting: list[Event] = field(default_factory=list)
    """Events not handed to ``write`` yet (the key is not known yet, or this tick's)."""
    dropped: bool = False


class InteractionLog:
    """Makes each session's interaction events from the ticks and hands them to ``write``."""

    def __init__(self, write: Write, min_confidence: float, whole_sessions: bool = False) -> None:
        """``min_confidence``: the speech the controller takes (``understood`` below it).
        ``whole_sessions``: write a session's events when it ends, not each tick's (the
        simulator: one write a session instead of one a tick, a fifth of a study's time;
        no crash can lose them there)."""
        self.write = write
        self.min_confidence = min_confidence
        self.whole_sessions = whole_sessions
        self._session: _Session | None = None

    def observe(
        self,
        now: datetime,
        user: str | None,
        decisions: Sequence[Decision],
        inputs: Sequence[object],
        key: str | None,
    ) -> None:
        """One tick at ``now``: the session's user (None without a session), the tick's
        decisions, its ``inputs`` (the messages it handled, in order) and the session's
        ``key`` (None while its user is not stored)."""
        session = self._session
        if session is not None and session.user_id != user:
            for message in inputs:
                self._input(session, message, now)
            session.offer = None  # the person left: an open offer was cut, not unanswered
            self._handle(session, (), decisions, now)
            self._close(session, now, decisions)
            inputs, decisions = (), ()
            session = self._session = None
        if session is None and user is not None:
            session = self._session = _Session(user, key, now)
            self._add(session, now, "arrived")
        if session is not None:
            session.key = session.key or key
            self._handle(session, inputs, decisions, now)
            if not self.whole_sessions or len(session.waiting) >= MAX_EVENTS:
                self._flush(session)

    # ------------------------------------------------------------------ what happened

    def _handle(
        self,
        session: _Session,
        inputs: Sequence[object],
        decisions: Sequence[Decision],
        now: datetime,
    ) -> None:
        """Inputs first: they came before the tick decided on them."""
        for message in inputs:
            self._input(session, message, now)
        for decision in decisions:
            self._decision(session, decision, now)

    def _input(self, session: _Session, message: object, now: datetime) -> None:
        if isinstance(message, Speech):
            self._answer(
                session,
                now,
                channel="voice",
                value=message.text[:_TEXT],
                confidence=message.confidence,
                understood=message.confidence >= self.min_confidence,
            )
        elif isinstance(message, ScreenChoice):
            self._answer(session, now, channel="screen", value=message.choice[:_TEXT])
        elif isinstance(message, Touch):
            self._add(
                session, now, "input", channel="touch", value=message.part, detail=message.kind
            )
        elif isinstance(message, Request):
            self._add(
                session,
                now,
                "input",
                channel="request",
                value=message.action,
                activity=_name(message.activity),
                by=(message.by or "request")[:64],
            )

    def _answer(self, session: _Session, now: datetime, **fields: Any) -> None:
        """Words or a tap: the open offer's (if any), with its delay since the offer."""
        offer = session.offer
        if offer is not None:
            offer.answered = True
            fields.update(
                offer=offer.number,
                offer_kind=offer.kind,
                delay_s=round(max(0.0, (now - offer.at).total_seconds()), 3),
            )
        self._add(session, now, "input", **fields)

    def _decision(self, session: _Session, decision: Decision, now: datetime) -> None:
        action, name = decision.action, decision.activity
        if action == "ask":
            self._end_offer(session, now)
            kind = ASKS.get(decision.reason, "confirm")
            self._offer(session, kind, _name(name), now)
            return
        event = ACTIVITY_EVENTS.get(action)
        if event is None:
            return
        if decision.reason in SESSION_ENDS:
            session.offer = None
        elif action != "pause":  # "continue or stop?" opens after the pause it is about
            self._end_offer(session, now)
        by: str | None = decision.chosen_by
        if action == "cancel":
            by = "user" if decision.reason in USER_STOPS else "robot"
        detail = (decision.reason or "")[:_TEXT]
        self._add(session, now, event, activity=_name(name), by=by, detail=detail)
        if action == "start" and name == "menu":
            self._offer(session, "menu", None, now)

    def _offer(self, session: _Session, kind: str, activity: str | None, now: datetime) -> None:
        session.offers += 1
        session.offer = _Offer(session.offers, kind, now, activity)
        self._add(session, now, "offered", offer=session.offers, offer_kind=kind, activity=activity)

    def _end_offer(self, session: _Session, now: datetime) -> None:
        """The open offer is over: note it if nobody answered it."""
        offer, session.offer = session.offer, None
        if offer is not None and not offer.answered:
            self._add(
                session,
                now,
                "unanswered",
                offer=offer.number,
                offer_kind=offer.kind,
                activity=offer.activity,
            )

    def _close(self, session: _Session, now: datetime, decisions: Sequence[Decision]) -> None:
        """The session ended at ``now``: an offer still open was cut, not unanswered."""
        session.offer = None
        why = next((d.reason for d in decisions if d.reason in SESSION_ENDS), None)
        self._add(session, now, "left", detail=why or "user_left")
        self._flush(session)
        if session.key is None and session.waiting:
            log.debug(
                "session of %s never stored: %d events forgotten",
                session.user_id,
                len(session.waiting),
            )

    # ------------------------------------------------------------------ the writes

    def _add(self, session: _Session, now: datetime, event: str, **fields: Any) -> None:
        if len(session.waiting) >= HELD_MAX:
            if not session.dropped:
                session.dropped = True
                log.warning(
                    "user %s not stored yet: later interaction events are dropped", session.user_id
                )
            return
        values = {name: value for name, value in fields.items() if value is not None}
        session.waiting.append({"seq": session.seq, "at": now, "event": event, **values})
        session.seq += 1

    def _flush(self, session: _Session) -> None:
        if session.key is None or not session.waiting:
            return
        events, session.waiting = session.waiting, []
        for start in range(0, len(events), MAX_EVENTS):  # a newcomer's held events
            self.write(session.user_id, session.key, events[start : start + MAX_EVENTS])


def _name(activity: str | None) -> str | None:
    """An activity's name as the store keeps it (at most 50 characters): a request may
    name anything, and one long name must not get the whole tick's events refused."""
    return activity[:50] if activity else None
