"""The store's rows: the checks of a value before it is written, the user's row as a
plain object, and the SQL statements of the write path.

The writes are SQLAlchemy Core statements built once here (SQLAlchemy caches their
compiled form by statement): an ORM unit of work cost nine tenths of a profile write.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from datetime import datetime
from typing import Any

from sqlalchemy import (
    Connection,
    Executable,
    RowMapping,
    Select,
    Table,
    bindparam,
    case,
    insert,
    select,
    update,
)

from dms.kernel.ids import InvalidIdentifier, check_identifier
from memory.db import dialect_module
from memory.errors import ProfileError, ProfileNotFound
from memory.models import (
    ActivityRunRow,
    ActivityScoreRow,
    AnswerRow,
    AppliedWriteRow,
    FeedbackRow,
    SessionRow,
    UserRow,
    UtcDateTime,
)
from memory.profile import ActivityScore, Profile


def check_time(name: str, value: Any) -> datetime:
    """``value`` if it is a timezone-aware datetime, else ProfileError naming ``name``."""
    if not isinstance(value, datetime) or value.tzinfo is None:
        raise ProfileError(f"{name}: must be a tz-aware UTC datetime (got {value!r:.60})")
    return value


def check_metrics(metrics: Any) -> None:
    """A session's metrics: a dict of names to finite numbers or None, nothing else
    (they are stored as JSON and read back by ``dms sessions``)."""
    if not isinstance(metrics, dict):
        raise ProfileError(f"metrics: must be a dict (got {metrics!r:.60})")
    for key, value in metrics.items():
        number = isinstance(value, int | float) and not isinstance(value, bool)
        if not isinstance(key, str) or not (value is None or (number and math.isfinite(value))):
            raise ProfileError(f"metrics: {key!r:.40} must be a finite number or null")


def check_user_id(user_id: Any) -> str:
    """The id rule of the bus (:mod:`dms.kernel.ids`), already trimmed: a store never renames."""
    try:
        trimmed = check_identifier(user_id, "user_id")
    except InvalidIdentifier as error:
        raise ProfileError(str(error)) from None
    if trimmed != user_id:
        raise ProfileError(f"user_id: has white space around it (got {user_id!r:.60})")
    return trimmed


def check_name(field: str, value: Any, max_length: int = 50) -> str:
    """``value`` if it is a non-empty string of at most ``max_length`` characters."""
    if not isinstance(value, str) or not value.strip() or len(value) > max_length:
        raise ProfileError(
            f"{field}: must be a non-empty string of at most {max_length} characters"
            f" (got {value!r:.60})"
        )
    return value


USERS: Table = UserRow.__table__  # type: ignore[assignment]
SCORES: Table = ActivityScoreRow.__table__  # type: ignore[assignment]
SESSIONS: Table = SessionRow.__table__  # type: ignore[assignment]
RUNS: Table = ActivityRunRow.__table__  # type: ignore[assignment]
FEEDBACK: Table = FeedbackRow.__table__  # type: ignore[assignment]
ANSWERS: Table = AnswerRow.__table__  # type: ignore[assignment]
APPLIED: Table = AppliedWriteRow.__table__  # type: ignore[assignment]
USER_COLUMNS = tuple(column.key for column in USERS.columns)
COUNTERS = ("feedback_sum", "feedback_count", "completions", "cancellations")


@dataclass
class UserFields:
    """The user's row as read for a field write, to be edited by the write's ``change``:
    a plain object, no ORM session behind it. Edits assign new values (a new dict for
    ``attributes``), never mutate what was read: the columns written are those that
    differ from the read."""

    user_id: str
    created_at: datetime
    updated_at: datetime
    name: str | None
    age: int | None
    sex: str | None
    language: str | None
    hearing: bool | None
    dialogue_mode: str | None
    interaction_style: str
    volume: float | None
    distance: float | None
    robot_initiative_frequency: str | None
    proactivity: str
    proactivity_confidence: float
    bondlevel: int | None
    favorite_room: str | None
    attributes: dict[str, Any]
    voice_failures: int
    screen_failures: int
    initiative_taken: int
    initiative_offered: int
    version: int


def profile_of(row: UserRow | UserFields, scores: dict[str, ActivityScore]) -> Profile:
    """The frozen :class:`Profile` of the user's columns and scores."""
    return Profile(
        user_id=row.user_id,
        created_at=row.created_at,
        updated_at=row.updated_at,
        name=row.name,
        age=row.age,
        sex=row.sex,
        language=row.language,
        hearing=row.hearing,
        dialogue_mode=row.dialogue_mode,
        interaction_style=row.interaction_style,
        volume=row.volume,
        distance=row.distance,
        robot_initiative_frequency=row.robot_initiative_frequency,
        proactivity=row.proactivity,
        proactivity_confidence=row.proactivity_confidence,
        bondlevel=row.bondlevel,
        favorite_room=row.favorite_room,
        attributes=dict(row.attributes or {}),
        scores=scores,
        voice_failures=row.voice_failures,
        screen_failures=row.screen_failures,
        initiative_taken=row.initiative_taken,
        initiative_offered=row.initiative_offered,
        version=row.version,
    )


def snapshot(row: UserRow) -> Profile:
    """The frozen :class:`Profile` of a loaded row."""
    return profile_of(
        row,
        {
            score.activity: ActivityScore(
                feedback_sum=score.feedback_sum,
                feedback_count=score.feedback_count,
                completions=score.completions,
                cancellations=score.cancellations,
            )
            for score in row.scores
        },
    )


def load_statement(lock: bool) -> Select[Any]:
    """The user joined with their scores, as the ORM's joined load read them; ``lock``:
    ``FOR UPDATE OF users`` (PostgreSQL's field writes)."""
    statement = (
        select(
            *USERS.columns,
            *(SCORES.c[name].label(f"score_{name}") for name in ("activity", *COUNTERS)),
        )
        .select_from(USERS.outerjoin(SCORES, USERS.c.user_id == SCORES.c.user_id))
        .where(USERS.c.user_id == bindparam("key_user_id"))
    )
    return statement.with_for_update(of=USERS) if lock else statement


LOAD = load_statement(lock=False)
LOAD_FOR_UPDATE = load_statement(lock=True)
USER_EXISTS = select(USERS.c.user_id).where(USERS.c.user_id == bindparam("key_user_id"))
SESSION_EXISTS = select(SESSIONS.c.id).where(SESSIONS.c.id == bindparam("key_id"))
TOUCH = (
    update(USERS)
    .where(USERS.c.user_id == bindparam("key_user_id"))
    .values(
        version=USERS.c.version + 1,
        updated_at=case(
            (
                USERS.c.updated_at < bindparam("key_when", type_=UtcDateTime()),
                bindparam("key_when", type_=UtcDateTime()),
            ),
            else_=USERS.c.updated_at,
        ),
    )
)
WRITE_FIELDS = update(USERS).where(
    USERS.c.user_id == bindparam("key_user_id"), USERS.c.version == bindparam("key_version")
)
"""Set the columns given as parameters if the version is still the one read (the
ORM's ``version_id_col`` check, by hand)."""
END_SESSION = update(SESSIONS).where(SESSIONS.c.id == bindparam("key_id"))
INSERT_USER = insert(USERS)
INSERT_SESSION = insert(SESSIONS)
INSERT_RUN = insert(RUNS)
INSERT_FEEDBACK = insert(FEEDBACK)
INSERT_ANSWER = insert(ANSWERS)
INSERT_APPLIED = insert(APPLIED)
APPLIED_RESULT = select(APPLIED.c.result).where(APPLIED.c.write_id == bindparam("key_write_id"))


def upserts(dialect: str) -> tuple[Executable, Executable] | None:
    """The dialect's (score upsert, user insert-if-missing), None without upserts.

    The score upsert adds all four counters (``n = n + excluded.n``); a counter the write
    does not move is added 0, which leaves it as it was."""
    if dialect not in ("sqlite", "postgresql"):
        return None
    module: Any = dialect_module(dialect)
    bump = module.insert(SCORES)
    return (
        bump.on_conflict_do_update(
            index_elements=["user_id", "activity"],
            set_={name: SCORES.c[name] + bump.excluded[name] for name in COUNTERS},
        ),
        module.insert(USERS).on_conflict_do_nothing(index_elements=["user_id"]),
    )


def load_user(
    connection: Connection, user_id: str, lock: bool = False
) -> tuple[RowMapping, dict[str, ActivityScore]]:
    """The user's columns and scores; ProfileNotFound without the user."""
    rows = connection.execute(LOAD_FOR_UPDATE if lock else LOAD, {"key_user_id": user_id}).all()
    if not rows:
        raise ProfileNotFound(f"no profile for user {user_id!r}")
    scores = {
        row.score_activity: ActivityScore(
            feedback_sum=row.score_feedback_sum,
            feedback_count=row.score_feedback_count,
            completions=row.score_completions,
            cancellations=row.score_cancellations,
        )
        for row in rows
        if row.score_activity is not None
    }
    return rows[0]._mapping, scores


def fields_of(columns: RowMapping) -> UserFields:
    """The user's row as read, as a :class:`UserFields` to edit."""
    return UserFields(**{name: columns[name] for name in USER_COLUMNS})
