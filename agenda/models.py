"""The agenda's tables (SQLAlchemy 2.x typed ORM).

Items are stored as data (user, kind, schedule, time zone, priority, text or
activity, lead, grace), never as pickled jobs. ``next_fire`` is the item's cursor:
the first occurrence not yet delivered or missed, moved forward in the same
transaction that logs the occurrence, so after a restart nothing runs twice and
nothing is skipped. ``agenda_occurrences`` is the log of deliveries and misses;
one row per (item, fire time) at most.

The schema belongs to ``agenda/migrations`` (Alembic, version table
``alembic_version_agenda``); change both together.
"""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Any

from sqlalchemy import DateTime, Integer, MetaData, String, Text, TypeDecorator, UniqueConstraint
from sqlalchemy.engine import Dialect
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column

NAMING = {
    "ix": "ix_%(column_0_label)s",
    "uq": "uq_%(table_name)s_%(column_0_name)s",
    "pk": "pk_%(table_name)s",
}


class UtcDateTime(TypeDecorator[datetime]):
    """A UTC instant stored without zone (SQLite and PostgreSQL alike), read back aware."""

    impl = DateTime
    cache_ok = True

    def process_bind_param(self, value: datetime | None, dialect: Dialect) -> datetime | None:
        if value is None:
            return None
        if value.tzinfo is None:
            raise ValueError("the agenda stores timezone-aware datetimes only")
        return value.astimezone(UTC).replace(tzinfo=None)

    def process_result_value(self, value: Any, dialect: Dialect) -> datetime | None:
        if value is None:
            return None
        assert isinstance(value, datetime)
        return value.replace(tzinfo=UTC)


class Base(DeclarativeBase):
    """The agenda's own metadata, apart from the profile store's."""

    metadata = MetaData(naming_convention=NAMING)


class ItemRow(Base):
    """One event or reminder of one user."""

    __tablename__ = "agenda_items"

    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=True)
    user_id: Mapped[str] = mapped_column(String(64), index=True)
    kind: Mapped[str] = mapped_column(String(16))
    activity: Mapped[str | None] = mapped_column(String(64))
    text: Mapped[str | None] = mapped_column(Text)
    schedule: Mapped[str] = mapped_column(String(8))
    spec: Mapped[str] = mapped_column(String(200))
    anchor: Mapped[datetime | None] = mapped_column(UtcDateTime())
    tz: Mapped[str] = mapped_column(String(64))
    priority: Mapped[str] = mapped_column(String(8))
    lead_s: Mapped[int] = mapped_column(Integer)
    grace_s: Mapped[int] = mapped_column(Integer)
    created_at: Mapped[datetime] = mapped_column(UtcDateTime())
    next_fire: Mapped[datetime | None] = mapped_column(UtcDateTime())


class OccurrenceRow(Base):
    """An occurrence delivered, or a run of consecutive missed occurrences of one item.

    Kept when the item is removed, so it does not reference the items table.
    """

    __tablename__ = "agenda_occurrences"
    __table_args__ = (UniqueConstraint("item_id", "fire_time"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=True)
    item_id: Mapped[int] = mapped_column(Integer)
    user_id: Mapped[str] = mapped_column(String(64), index=True)
    kind: Mapped[str] = mapped_column(String(16))
    what: Mapped[str] = mapped_column(Text)
    outcome: Mapped[str] = mapped_column(String(16))
    fire_time: Mapped[datetime] = mapped_column(UtcDateTime())
    last_fire_time: Mapped[datetime] = mapped_column(UtcDateTime())
    count: Mapped[int] = mapped_column(Integer)
    recorded_at: Mapped[datetime] = mapped_column(UtcDateTime())
    reason: Mapped[str] = mapped_column(Text)


class ClaimRow(Base):
    """Which robot took one occurrence of an item: the fleet's guard against twice.

    A robot that sees the item's user inserts the row before it delivers; the primary key
    lets one robot in (``INSERT ... ON CONFLICT DO NOTHING``: the other one's insert
    changes no row). The row outlives the delivery by :data:`agenda.claims.CLAIMS_KEEP_S`.
    """

    __tablename__ = "agenda_claims"

    item_id: Mapped[int] = mapped_column(Integer, primary_key=True)
    fire_time: Mapped[datetime] = mapped_column(UtcDateTime(), primary_key=True)
    user_id: Mapped[str] = mapped_column(String(64), index=True)
    claimed_by: Mapped[str] = mapped_column(String(200))
    claimed_at: Mapped[datetime] = mapped_column(UtcDateTime())
