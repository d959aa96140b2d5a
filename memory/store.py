"""The profile store: one user's profile and history in any SQLAlchemy database.

Every public method opens its own short session and commits before it returns, so
the store is safe to call from several threads and an acknowledged write survives a
crash (SQLite: WAL with ``synchronous=FULL``). Database failures while running are
classified (:func:`memory.failures.classify`): :class:`StoreUnavailable` for a passing
trouble (a lock, a lost connection, a timeout: retry later), :class:`StoreRefused` for a
refusal of this one request (a constraint, a value the database cannot hold, a missing
table: retrying will not help). The daemon spools the first and quarantines the second.

Several robots may write one profile at once (docs/fleet.md). No write loses
another's: counters of activity scores are incremented in the database (an upsert,
``INSERT ... ON CONFLICT DO UPDATE SET n = n + excluded.n``); histories are appended;
the other fields are written through the row's version (:mod:`memory.writes`). Writes
are the Core statements of :mod:`memory.rows`; exports, erasure and the other reads of
many rows use the ORM. A write that carries a ``write_id`` (the daemon's all do) is
applied once, also when a spool replayed after a crash brings it again.
"""

from __future__ import annotations

import math
from contextlib import suppress
from datetime import datetime
from typing import Any

from sqlalchemy import Connection, delete, select

from memory import interactions, proactivity, user_data
from memory.errors import ProfileError, ProfileNotFound, StoreRefused
from memory.failures import Conflict, classify
from memory.models import (
    ActivityRunRow,
    ActivityScoreRow,
    AnswerRow,
    AppliedWriteRow,
    FeedbackRow,
    InteractionEventRow,
    SessionRow,
    UserRow,
)
from memory.profile import INTERACTION_STYLES, MAX_ATTRIBUTES, Profile, validate_fields
from memory.rows import (
    APPLIED_RESULT,
    END_SESSION,
    INSERT_ANSWER,
    INSERT_FEEDBACK,
    INSERT_RUN,
    INSERT_SESSION,
    INSERT_USER,
    SESSION_EXISTS,
    UserFields,
    check_metrics,
    check_name,
    check_time,
    check_user_id,
    snapshot,
)
from memory.user_data import UserData, register_user_data
from memory.writes import APPLIED_KEEP_DAYS, StoreDatabase

__all__ = [
    "APPLIED_KEEP_DAYS",
    "COMPLETED_OUTCOMES",
    "FAILURES_TO_SWITCH",
    "ProfileStore",
    "UserData",
    "classify",
    "register_user_data",
    "snapshot",
]

FAILURES_TO_SWITCH = 3
"""Consecutive unanswered prompts on one channel after which the style switches (Table 2)."""

COMPLETED_OUTCOMES = frozenset({"completed", "done", "succeeded", "success"})


class ProfileStore(StoreDatabase):
    """Profiles and their history in the database at ``url``.

    Raises:
        ProfileError: the database cannot be opened (one-line message).
        SchemaOutOfDate: the database needs ``dms db upgrade --db URL``.
    """

    # ------------------------------------------------------------------ profiles

    def get_or_create(self, user_id: str, now: datetime) -> Profile:
        """Step 5: the user's profile, or a new empty one for a new user.

        Two robots meeting a new user at once make one profile (the second insert is a
        no-op in the database)."""
        check_user_id(user_id)
        check_time("now", now)
        values: dict[str, Any] = {
            "user_id": user_id,
            "created_at": now,
            "updated_at": now,
            "interaction_style": "voice",
            "proactivity": "unknown",
            "proactivity_confidence": 0.0,
            "attributes": {},
            "voice_failures": 0,
            "screen_failures": 0,
            "initiative_taken": 0,
            "initiative_offered": 0,
            "version": 1,
        }
        # The user is known: one SELECT, no transaction.
        with self._read_connection() as connection, suppress(ProfileNotFound):
            return self._fresh(connection, user_id)
        try:
            with self._transaction() as connection:
                if self._upserts is not None:
                    connection.execute(self._upserts[1], values)
                else:
                    connection.execute(INSERT_USER, values)
                return self._fresh(connection, user_id)
        except Conflict:
            pass
        # Another writer created it between our read and our insert.
        return self.get(user_id)

    def last_run(self, user_id: str) -> dict[str, Any] | None:
        """The user's latest activity run at any robot of the fleet (``activity``,
        ``ended``, ``outcome``, ``chosen_by``), None if there is none: a robot that
        meets her reads it to resume what another robot's session end cut."""
        check_user_id(user_id)
        with self._read() as session:
            row = session.scalars(
                select(ActivityRunRow)
                .where(ActivityRunRow.user_id == user_id)
                .order_by(ActivityRunRow.ended_at.desc(), ActivityRunRow.id.desc())
                .limit(1)
            ).first()
        if row is None:
            return None
        return {
            "activity": row.activity,
            "ended": row.ended_at,
            "outcome": row.outcome,
            "chosen_by": row.chosen_by,
        }

    def update(
        self,
        user_id: str,
        now: datetime,
        *,
        write_id: Any = None,  # str | None; Any so that callers may pass **fields: object
        **fields: Any,
    ) -> Profile:
        """Set profile fields or free attributes; None clears one.

        Only the fields named are written, on the row as it is when the write lands: a
        concurrent write of other fields or attributes is kept (``write_id``: see
        :meth:`_once`).

        Raises:
            ProfileError: naming the field whose name or value is wrong (nothing is written).
        """
        check_time("now", now)
        columns, attributes = validate_fields(fields)

        def change(row: UserFields) -> None:
            for name, value in columns.items():
                setattr(row, name, value)
            if attributes:
                merged = dict(row.attributes or {})
                for name, value in attributes.items():
                    if value is None:
                        merged.pop(name, None)
                    else:
                        merged[name] = value
                if len(merged) > MAX_ATTRIBUTES:
                    raise ProfileError(f"attributes: at most {MAX_ATTRIBUTES} free attributes")
                row.attributes = merged
            row.updated_at = now

        return self._field_write(write_id, user_id, change)

    def list_ids(self) -> list[str]:
        """Every stored user id, sorted."""
        with self._session() as session:
            return list(session.scalars(select(UserRow.user_id).order_by(UserRow.user_id)))

    def export(self, user_id: str) -> dict[str, Any]:
        """Everything stored about the user, history included, as JSON-able data.

        Registered :class:`UserData` parts add their own key (``agenda``).
        """
        with self._session() as session:
            row = self._user(session, user_id)
            profile = snapshot(row).model_dump(mode="json")

            def rows(model: Any) -> list[Any]:
                return list(
                    session.scalars(
                        select(model).where(model.user_id == user_id).order_by(model.id)
                    )
                )

            data: dict[str, Any] = {
                "profile": profile,
                "sessions": [
                    {
                        "id": s.id,
                        "started": s.started_at.isoformat(),
                        "ended": s.ended_at.isoformat() if s.ended_at else None,
                        "metrics": s.metrics,
                    }
                    for s in rows(SessionRow)
                ],
                "activities": [
                    {
                        "activity": r.activity,
                        "session_id": r.session_id,
                        "started": r.started_at.isoformat(),
                        "ended": r.ended_at.isoformat(),
                        "outcome": r.outcome,
                        "chosen_by": r.chosen_by,
                        "cancelled": r.cancelled,
                    }
                    for r in rows(ActivityRunRow)
                ],
                "feedback": [
                    {"activity": f.activity, "score": f.score, "time": f.at.isoformat()}
                    for f in rows(FeedbackRow)
                ],
                "answers": [
                    {
                        "question": a.question_id,
                        "answer": a.answer,
                        "applied": a.applied,
                        "time": a.at.isoformat(),
                    }
                    for a in rows(AnswerRow)
                ],
                "interactions": [
                    {
                        "session_id": e.session_id,
                        "seq": e.seq,
                        "time": e.at.isoformat(),
                        "event": e.event,
                        **{
                            name: getattr(e, name)
                            for name in interactions.COLUMNS[6:]
                            if getattr(e, name) is not None
                        },
                    }
                    for e in rows(InteractionEventRow)
                ],
            }
            for part in user_data.parts():
                extra = part.export_user(session, user_id)
                if extra is not None:
                    data[part.name] = extra
            return data

    def erase(self, user_id: str) -> None:
        """Delete everything about the user, history included (and so from training).

        The registered :class:`UserData` parts (the agenda's items and log) go in the
        same transaction: either nothing or everything of the user is deleted.
        """
        with self._session() as session:
            self._user(session, user_id)
            for part in user_data.parts():
                part.erase_user(session, user_id)
            # Explicit deletes, children first: no reliance on the backend's cascade.
            for model in (
                AppliedWriteRow,
                InteractionEventRow,
                AnswerRow,
                FeedbackRow,
                ActivityRunRow,
                SessionRow,
                ActivityScoreRow,
            ):
                session.execute(delete(model).where(model.user_id == user_id))
            session.execute(delete(UserRow).where(UserRow.user_id == user_id))

    # ------------------------------------------------------------------ history

    def start_session(self, user_id: str, now: datetime, write_id: str | None = None) -> int:
        """A new interaction session; its id for :meth:`end_session` and runs.

        With a ``write_id`` (the daemon's session key) a replay returns the same session."""
        check_time("now", now)

        def change(connection: Connection) -> int:
            self._check_user(connection, user_id)
            inserted = connection.execute(INSERT_SESSION, {"user_id": user_id, "started_at": now})
            (session_id,) = inserted.inserted_primary_key or (None,)
            if not isinstance(session_id, int):
                raise StoreRefused(f"session of {user_id!r}: the database gave no id")
            return session_id

        def again(result: int | None) -> int:
            if result is None:
                raise StoreRefused(f"write {write_id}: applied, but its session is gone")
            return result

        return self._once(write_id, user_id, change, again, result=lambda answer: answer)

    def end_session(
        self, session_id: int, now: datetime, metrics: dict[str, Any] | None = None
    ) -> None:
        """Close the session (the user left, or the daemon stops), with its Table 4
        ``metrics`` when given (``dms.kernel.session_metrics``: names to numbers or None)."""
        check_time("now", now)
        if metrics is not None:
            check_metrics(metrics)
        values: dict[str, Any] = {"ended_at": now, "key_id": session_id}
        if metrics is not None:
            values["metrics"] = dict(metrics)
        with self._transaction() as connection:
            if connection.execute(SESSION_EXISTS, {"key_id": session_id}).first() is None:
                raise ProfileError(f"session_id: no session {session_id!r}")
            connection.execute(END_SESSION, values)

    def sessions(self, since: datetime | None = None) -> list[dict[str, Any]]:
        """Every session (of every user) started at or after ``since``, oldest first:
        ``{"session", "user", "started", "ended", "metrics"}`` (times as ISO strings,
        ``ended`` and ``metrics`` None while a session is open or was stored without).
        For ``dms sessions``: a deployment's own Table 4."""
        if since is not None:
            check_time("since", since)
        query = select(SessionRow).order_by(SessionRow.started_at, SessionRow.id)
        if since is not None:
            query = query.where(SessionRow.started_at >= since)
        with self._session() as session:
            return [
                {
                    "session": row.id,
                    "user": row.user_id,
                    "started": row.started_at.isoformat(),
                    "ended": row.ended_at.isoformat() if row.ended_at else None,
                    "metrics": dict(row.metrics) if row.metrics is not None else None,
                }
                for row in session.scalars(query)
            ]

    def record_interactions(
        self,
        user_id: str,
        session: int | str | None,
        events: list[dict[str, Any]],
        write_id: str | None = None,
    ) -> int:
        """Append interaction events (:mod:`memory.interactions`) to ``session``'s record;
        how many were stored.

        ``session``: the session's id, or the key the daemon named it by (the
        ``write_id`` of its :meth:`start_session`, found in ``applied_writes``), or None
        for events of no stored session. A key that names no session stores the events
        without one (they keep their user and times)."""
        check_user_id(user_id)
        rows = interactions.check_events(events)
        if not (session is None or isinstance(session, str)) and (
            isinstance(session, bool) or not isinstance(session, int)
        ):
            raise ProfileError(
                f"session: must be an id, a session key or null (got {session!r:.60})"
            )

        def change(connection: Connection) -> int:
            self._check_user(connection, user_id)
            session_id: int | None = None
            if isinstance(session, str):
                found = connection.execute(APPLIED_RESULT, {"key_write_id": session}).first()
                session_id = found[0] if found is not None else None
            elif session is not None:
                if connection.execute(SESSION_EXISTS, {"key_id": session}).first() is None:
                    raise ProfileError(f"session: no session {session!r}")
                session_id = session
            interactions.insert_events(connection, user_id, session_id, rows)
            return len(rows)

        return self._once(write_id, user_id, change, lambda _: len(rows))

    def interaction_events(self, since: datetime | None = None) -> list[dict[str, Any]]:
        """Every interaction event of the sessions started at or after ``since`` (all
        when None), one flat row each (:data:`memory.interactions.COLUMNS`), by session
        and in order: what ``dms sessions export --events`` prints."""
        if since is not None:
            check_time("since", since)
        with self._read_connection() as connection:
            return interactions.read_events(connection, since)

    def record_activity(
        self,
        user_id: str,
        activity: str,
        started: datetime,
        ended: datetime,
        outcome: str,
        chosen_by: str,
        cancelled: bool,
        session_id: int | None = None,
        write_id: str | None = None,
    ) -> Profile:
        """Log one activity run; a completion or cancellation updates the user's score."""
        check_name("activity", activity)
        check_time("started", started)
        check_time("ended", ended)
        check_name("outcome", outcome)
        check_name("chosen_by", chosen_by, 20)
        if not isinstance(cancelled, bool):
            raise ProfileError(f"cancelled: must be true or false (got {cancelled!r:.60})")
        if ended < started:
            raise ProfileError("ended: is before started")

        def change(connection: Connection) -> Profile:
            self._touch(connection, user_id, ended)
            if (
                session_id is not None
                and connection.execute(SESSION_EXISTS, {"key_id": session_id}).first() is None
            ):
                raise ProfileError(f"session_id: no session {session_id!r}")
            connection.execute(
                INSERT_RUN,
                {
                    "user_id": user_id,
                    "session_id": session_id,
                    "activity": activity,
                    "started_at": started,
                    "ended_at": ended,
                    "outcome": outcome,
                    "chosen_by": chosen_by,
                    "cancelled": cancelled,
                },
            )
            if cancelled:
                self._bump_score(connection, user_id, activity, cancellations=1)
            elif outcome in COMPLETED_OUTCOMES:
                self._bump_score(connection, user_id, activity, completions=1)
            return self._fresh(connection, user_id)

        return self._once(write_id, user_id, change, lambda _: self.get(user_id))

    def record_feedback(
        self,
        user_id: str,
        activity: str,
        score: float,
        now: datetime,
        write_id: str | None = None,
    ) -> Profile:
        """Step 7: how much the user liked ``activity``, 0 (not at all) to 1 (a lot)."""
        check_name("activity", activity)
        check_time("now", now)
        if (
            isinstance(score, bool)
            or not isinstance(score, int | float)
            or not math.isfinite(score)
            or not 0 <= score <= 1
        ):
            raise ProfileError(f"score: must be a number between 0 and 1 (got {score!r:.60})")

        def change(connection: Connection) -> Profile:
            self._touch(connection, user_id, now)
            connection.execute(
                INSERT_FEEDBACK,
                {"user_id": user_id, "activity": activity, "score": float(score), "at": now},
            )
            self._bump_score(
                connection, user_id, activity, feedback_sum=float(score), feedback_count=1
            )
            return self._fresh(connection, user_id)

        return self._once(write_id, user_id, change, lambda _: self.get(user_id))

    def record_answer(
        self,
        user_id: str,
        question_id: str,
        answer: str,
        now: datetime,
        write_id: str | None = None,
    ) -> Profile:
        """Step 8: log an answer to a general question and store the fields it fills."""
        from memory.questions import QuestionBank

        check_name("question_id", question_id, 100)
        check_time("now", now)
        if not isinstance(answer, str) or len(answer) > 2000:
            raise ProfileError("answer: must be a string of at most 2000 characters")
        bank = QuestionBank.default()
        question = bank.get(question_id)
        applied = bank.parse(question, answer) if question is not None else None
        columns, attributes = validate_fields(applied or {})

        def change(row: UserFields) -> None:
            for name, value in columns.items():
                setattr(row, name, value)
            if attributes:
                row.attributes = {**(row.attributes or {}), **attributes}
            if "robot_initiative_frequency" in columns:  # seeds the proactivity estimate
                self._estimate_proactivity(row)
            row.updated_at = now

        def log(connection: Connection) -> None:
            connection.execute(
                INSERT_ANSWER,
                {
                    "user_id": user_id,
                    "question_id": question_id,
                    "answer": answer,
                    "applied": applied,
                    "at": now,
                },
            )

        return self._field_write(write_id, user_id, change, also=log)

    @staticmethod
    def _estimate_proactivity(row: UserFields) -> None:
        """Proactivity from the record of chances (:mod:`memory.proactivity`)."""
        level, confidence = proactivity.estimate(
            row.initiative_taken,
            row.initiative_offered,
            row.robot_initiative_frequency,
            row.proactivity,
        )
        row.proactivity = level
        row.proactivity_confidence = confidence

    def record_interaction(
        self,
        user_id: str,
        channel: str,
        answered: bool,
        now: datetime,
        write_id: str | None = None,
    ) -> Profile:
        """Table 2: count unanswered prompts per channel; after
        :data:`FAILURES_TO_SWITCH` in a row on the current style, switch to the other."""
        if channel not in INTERACTION_STYLES:
            raise ProfileError(f"channel: must be voice or screen (got {channel!r:.60})")
        if not isinstance(answered, bool):
            raise ProfileError(f"answered: must be true or false (got {answered!r:.60})")
        check_time("now", now)
        attribute = f"{channel}_failures"

        def change(row: UserFields) -> None:
            if answered:
                setattr(row, attribute, 0)
            else:
                failures = getattr(row, attribute) + 1
                setattr(row, attribute, failures)
                if failures >= FAILURES_TO_SWITCH and row.interaction_style == channel:
                    row.interaction_style = "screen" if channel == "voice" else "voice"
                    setattr(row, attribute, 0)
            row.updated_at = now

        return self._field_write(write_id, user_id, change)

    def record_initiative(
        self, user_id: str, took_initiative: bool, now: datetime, write_id: str | None = None
    ) -> Profile:
        """Count a chance to take the initiative; re-estimate proactivity and its confidence."""
        if not isinstance(took_initiative, bool):
            raise ProfileError(
                f"took_initiative: must be true or false (got {took_initiative!r:.60})"
            )
        check_time("now", now)

        def change(row: UserFields) -> None:
            row.initiative_taken, row.initiative_offered = proactivity.forget(
                row.initiative_taken + int(took_initiative), row.initiative_offered + 1
            )
            self._estimate_proactivity(row)
            row.updated_at = now

        return self._field_write(write_id, user_id, change)

    # ------------------------------------------------------------------ training data

    def training_rows(self) -> list[tuple[dict[str, Any], dict[str, float]]]:
        """(features, own mean liking per activity) of every stored user with evidence.

        What :meth:`memory.PreferenceModel.train` learns from: an erased user is gone
        from it at once.
        """
        with self._session() as session:
            out = []
            for row in session.scalars(select(UserRow).order_by(UserRow.user_id)).unique():
                profile = snapshot(row)
                means = {
                    name: mean
                    for name, score in profile.scores.items()
                    if (mean := score.mean()) is not None
                }
                features = profile.features()
                if len(means) >= 2 and features:
                    out.append((features, means))
            return out
