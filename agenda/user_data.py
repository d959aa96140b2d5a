"""The agenda's part of ``dms users export|erase``: a user's items, log and claims.

Registered with the profile store when the agenda is imported, so that
:meth:`memory.ProfileStore.export` and :meth:`memory.ProfileStore.erase` cover the
agenda's rows in their own transaction without the memory package importing this one.
"""

from __future__ import annotations

from datetime import datetime
from typing import Any

from sqlalchemy import delete, inspect, select
from sqlalchemy.orm import Session

from agenda.models import ClaimRow, ItemRow, OccurrenceRow
from memory.user_data import register_user_data


class AgendaUserData:
    """The agenda's part of ``dms users export|erase``: the user's items and log.

    Registered with the profile store, which calls it inside its own transaction. A
    database without the agenda's tables (a store made by ``memory`` alone) has none.
    """

    name = "agenda"

    def export_user(self, session: Session, user_id: str) -> dict[str, list[dict[str, Any]]] | None:
        """Every column of the user's items and log rows, oldest first."""
        if not _has_tables(session):
            return None
        return {
            "items": [_stored(row) for row in session.scalars(_of(ItemRow, user_id))],
            "log": [_stored(row) for row in session.scalars(_of(OccurrenceRow, user_id))],
            "claims": [
                _stored(row)
                for row in session.scalars(
                    select(ClaimRow)
                    .where(ClaimRow.user_id == user_id)
                    .order_by(ClaimRow.fire_time, ClaimRow.item_id)
                )
            ],
        }

    def erase_user(self, session: Session, user_id: str) -> None:
        """Delete the user's log and items."""
        if not _has_tables(session):
            return
        session.execute(delete(ClaimRow).where(ClaimRow.user_id == user_id))
        session.execute(delete(OccurrenceRow).where(OccurrenceRow.user_id == user_id))
        session.execute(delete(ItemRow).where(ItemRow.user_id == user_id))


def _has_tables(session: Session) -> bool:
    names = {ItemRow.__tablename__, OccurrenceRow.__tablename__, ClaimRow.__tablename__}
    return names <= set(inspect(session.connection()).get_table_names())


def _of(model: type[ItemRow] | type[OccurrenceRow], user_id: str) -> Any:
    return select(model).where(model.user_id == user_id).order_by(model.id)


def _stored(row: ItemRow | OccurrenceRow | ClaimRow) -> dict[str, Any]:
    """A row as stored, times in ISO 8601."""
    out: dict[str, Any] = {}
    for column in row.__table__.columns:
        value = getattr(row, column.key)
        out[column.key] = value.isoformat() if isinstance(value, datetime) else value
    return out


USER_DATA = AgendaUserData()
register_user_data(USER_DATA)
