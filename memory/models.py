"""The profile tables, as SQLAlchemy 2 typed ORM classes.

``users`` holds one row per user (general information, interaction preferences,
proactivity, free attributes); ``activity_scores`` the user's own running scores per
activity; ``sessions``, ``activity_runs``, ``feedback``, ``answers`` and
``interaction_events`` (:mod:`memory.interactions`) the history.
Every history row hangs from its user with ``ON DELETE CASCADE`` so that erasing a
user erases everything. Schema changes go through ``memory/migrations``.

Several robots write the same profile (docs/fleet.md): ``users.version`` is bumped by
every write and checked by the ORM (``version_id_col``), so a field write made on a
stale read fails and is retried on the fresh row; counters are incremented in the
database; ``applied_writes`` records each write's unique id in the write's own
transaction, so a write replayed from a spool is applied once.
"""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Any

from sqlalchemy import (
    JSON,
    Boolean,
    DateTime,
    Dialect,
    Float,
    ForeignKey,
    Integer,
    String,
    Text,
    TypeDecorator,
)
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column, relationship


class UtcDateTime(TypeDecorator[datetime]):
    """A tz-aware UTC datetime on every backend (SQLite keeps no time zone)."""

    impl = DateTime(timezone=True)
    cache_ok = True

    def process_bind_param(self, value: datetime | None, dialect: Dialect) -> datetime | None:
        if value is None:
            return None
        if value.tzinfo is None:
            raise ValueError("naive datetime: pass a tz-aware UTC time")
        value = value.astimezone(UTC)
        return value.replace(tzinfo=None) if dialect.name == "sqlite" else value

    def process_result_value(self, value: datetime | None, dialect: Dialect) -> datetime | None:
        if value is None:
            return None
        if value.tzinfo is None:
            return value.replace(tzinfo=UTC)
        return value.astimezone(UTC)


class Base(DeclarativeBase):
    """The memory package's own metadata (the agenda has its own)."""


class UserRow(Base):
    """One user's profile: everything but the history."""

    __tablename__ = "users"

    user_id: Mapped[str] = mapped_column(String(200), primary_key=True)
    created_at: Mapped[datetime] = mapped_column(UtcDateTime())
    updated_at: Mapped[datetime] = mapped_column(UtcDateTime())
    name: Mapped[str | None] = mapped_column(String(200))
    age: Mapped[int | None] = mapped_column(Integer)
    sex: Mapped[str | None] = mapped_column(String(20))
    language: Mapped[str | None] = mapped_column(String(50))
    hearing: Mapped[bool | None] = mapped_column(Boolean)
    dialogue_mode: Mapped[str | None] = mapped_column(String(20))
    interaction_style: Mapped[str] = mapped_column(String(20), default="voice")
    volume: Mapped[float | None] = mapped_column(Float)
    distance: Mapped[float | None] = mapped_column(Float)
    robot_initiative_frequency: Mapped[str | None] = mapped_column(String(20))
    proactivity: Mapped[str] = mapped_column(String(20), default="unknown")
    proactivity_confidence: Mapped[float] = mapped_column(Float, default=0.0)
    bondlevel: Mapped[int | None] = mapped_column(Integer)
    favorite_room: Mapped[str | None] = mapped_column(String(100))
    attributes: Mapped[dict[str, Any]] = mapped_column(JSON, default=dict)
    voice_failures: Mapped[int] = mapped_column(Integer, default=0)
    screen_failures: Mapped[int] = mapped_column(Integer, default=0)
    initiative_taken: Mapped[int] = mapped_column(Integer, default=0)
    initiative_offered: Mapped[int] = mapped_column(Integer, default=0)
    version: Mapped[int] = mapped_column(Integer, default=1, server_default="0")
    """Bumped by every write of the profile; an ORM update checks it (optimistic lock)."""

    scores: Mapped[list[ActivityScoreRow]] = relationship(
        cascade="all, delete-orphan", passive_deletes=True, lazy="joined"
    )

    __mapper_args__ = {"version_id_col": version}  # noqa: RUF012 (SQLAlchemy's own dict)


class ActivityScoreRow(Base):
    """The user's own evidence about one activity: feedback, completions, cancellations."""

    __tablename__ = "activity_scores"

    user_id: Mapped[str] = mapped_column(
        ForeignKey("users.user_id", ondelete="CASCADE"), primary_key=True
    )
    activity: Mapped[str] = mapped_column(String(50), primary_key=True)
    feedback_sum: Mapped[float] = mapped_column(Float, default=0.0)
    feedback_count: Mapped[int] = mapped_column(Integer, default=0)
    completions: Mapped[int] = mapped_column(Integer, default=0)
    cancellations: Mapped[int] = mapped_column(Integer, default=0)


class SessionRow(Base):
    """One interaction session: from the user being ready to them leaving."""

    __tablename__ = "sessions"

    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=True)
    user_id: Mapped[str] = mapped_column(
        ForeignKey("users.user_id", ondelete="CASCADE"), index=True
    )
    started_at: Mapped[datetime] = mapped_column(UtcDateTime())
    ended_at: Mapped[datetime | None] = mapped_column(UtcDateTime())
    metrics: Mapped[dict[str, Any] | None] = mapped_column(JSON)
    """The session's Table 4 metrics (``dms.kernel.session_metrics``), set when it ends."""


class ActivityRunRow(Base):
    """One run of an activity with this user."""

    __tablename__ = "activity_runs"

    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=True)
    user_id: Mapped[str] = mapped_column(
        ForeignKey("users.user_id", ondelete="CASCADE"), index=True
    )
    session_id: Mapped[int | None] = mapped_column(
        ForeignKey("sessions.id", ondelete="CASCADE"), index=True
    )
    activity: Mapped[str] = mapped_column(String(50))
    started_at: Mapped[datetime] = mapped_column(UtcDateTime())
    ended_at: Mapped[datetime] = mapped_column(UtcDateTime())
    outcome: Mapped[str] = mapped_column(String(50))
    chosen_by: Mapped[str] = mapped_column(String(20))
    cancelled: Mapped[bool] = mapped_column(Boolean)


class FeedbackRow(Base):
    """One answer to "how much did you like it?", as a score in 0..1."""

    __tablename__ = "feedback"

    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=True)
    user_id: Mapped[str] = mapped_column(
        ForeignKey("users.user_id", ondelete="CASCADE"), index=True
    )
    activity: Mapped[str] = mapped_column(String(50))
    score: Mapped[float] = mapped_column(Float)
    at: Mapped[datetime] = mapped_column(UtcDateTime())


class AnswerRow(Base):
    """One answer to a general question, with the fields it filled (if understood)."""

    __tablename__ = "answers"

    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=True)
    user_id: Mapped[str] = mapped_column(
        ForeignKey("users.user_id", ondelete="CASCADE"), index=True
    )
    question_id: Mapped[str] = mapped_column(String(100))
    answer: Mapped[str] = mapped_column(Text)
    applied: Mapped[dict[str, Any] | None] = mapped_column(JSON)
    at: Mapped[datetime] = mapped_column(UtcDateTime())


class InteractionEventRow(Base):
    """One interaction event of a session: an offer, an input, a decision about the user's
    activity, the arrival or the departure (:mod:`memory.interactions` says each column)."""

    __tablename__ = "interaction_events"

    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=True)
    user_id: Mapped[str] = mapped_column(
        ForeignKey("users.user_id", ondelete="CASCADE"), index=True
    )
    session_id: Mapped[int | None] = mapped_column(
        ForeignKey("sessions.id", ondelete="CASCADE"), index=True
    )
    seq: Mapped[int] = mapped_column(Integer)
    at: Mapped[datetime] = mapped_column(UtcDateTime())
    event: Mapped[str] = mapped_column(String(20))
    offer: Mapped[int | None] = mapped_column(Integer)
    offer_kind: Mapped[str | None] = mapped_column(String(20))
    channel: Mapped[str | None] = mapped_column(String(20))
    value: Mapped[str | None] = mapped_column(String(200))
    confidence: Mapped[float | None] = mapped_column(Float)
    understood: Mapped[bool | None] = mapped_column(Boolean)
    delay_s: Mapped[float | None] = mapped_column(Float)
    activity: Mapped[str | None] = mapped_column(String(50))
    by: Mapped[str | None] = mapped_column(String(64))
    detail: Mapped[str | None] = mapped_column(String(200))


class AppliedWriteRow(Base):
    """A write already applied: its unique id, recorded in the write's own transaction.

    A write replayed from a spool (after a crash, or the in-flight write of a writer
    that did not finish) finds its id here and is not applied again. ``result`` keeps
    what the write returned when a replay needs it (the id of a session it started).
    Old rows are pruned (:data:`memory.writes.APPLIED_KEEP_DAYS`).
    """

    __tablename__ = "applied_writes"

    write_id: Mapped[str] = mapped_column(String(64), primary_key=True)
    user_id: Mapped[str] = mapped_column(
        ForeignKey("users.user_id", ondelete="CASCADE"), index=True
    )
    result: Mapped[int | None] = mapped_column(Integer)
    applied_at: Mapped[datetime] = mapped_column(UtcDateTime(), index=True)
