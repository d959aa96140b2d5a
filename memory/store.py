"""The profile store: one user's profile and history in any SQLAlchemy database.

Every public method opens its own short session and commits before it returns, so
the store is safe to call from several threads and an acknowledged write survives a
crash (SQLite: WAL with ``synchronous=FULL``). Database failures while running are
classified (:func:`classify`): :class:`StoreUnavailable` for a passing trouble (a lock,
a lost connection, a timeout: retry later), :class:`StoreRefused` for a refusal of this
one request (a constraint, a value the database cannot hold, a missing table: retrying
will not help). The daemon spools the first and quarantines the second.

Several robots may write one profile at once (docs/fleet.md). No write loses
another's: counters of activity scores are incremented in the database (an upsert,
``INSERT ... ON CONFLICT DO UPDATE SET n = n + excluded.n``); histories are appended;
the other fields are written through the row's version (``users.version``: the UPDATE
names the version read), and a write made on a stale read is retried on the fresh row
(its fields are merged into the other write's, never over a row it did not read).
Writes are SQLAlchemy Core statements built once (an ORM unit of work was nine tenths
of a write's cost); exports, erasure and the other reads of many rows use the ORM.
A write that carries a ``write_id`` (the daemon's all do) records it in
``applied_writes`` in the same transaction and is skipped when it comes again (a spool
replayed after a crash).
"""

from __future__ import annotations

import math
import random
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from typing import Any, Protocol, TypeVar

from sqlalchemy import (
    Connection,
    Executable,
    RowMapping,
    Select,
    Table,
    bindparam,
    case,
    delete,
    insert,
    inspect,
    select,
    update,
)
from sqlalchemy.dialects import postgresql, sqlite
from sqlalchemy.engine import make_url
from sqlalchemy.exc import (
    ArgumentError,
    DatabaseError,
    DBAPIError,
    DisconnectionError,
    IntegrityError,
    InterfaceError,
    InternalError,
    OperationalError,
    SQLAlchemyError,
)
from sqlalchemy.exc import TimeoutError as PoolTimeout
from sqlalchemy.orm import Session, sessionmaker
from sqlalchemy.orm.exc import StaleDataError

from dms.kernel.ids import InvalidIdentifier, check_identifier
from memory import migrations, proactivity
from memory.db import as_url, default_url, make_engine
from memory.errors import (
    ProfileError,
    ProfileNotFound,
    SchemaOutOfDate,
    StoreDamaged,
    StoreRefused,
    StoreUnavailable,
)
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
from memory.profile import (
    INTERACTION_STYLES,
    MAX_ATTRIBUTES,
    ActivityScore,
    Profile,
    validate_fields,
)

FAILURES_TO_SWITCH = 3
"""Consecutive unanswered prompts on one channel after which the style switches (Table 2)."""


COMPLETED_OUTCOMES = frozenset({"completed", "done", "succeeded", "success"})

MAX_ATTEMPTS = 50
"""Tries of one field write whose row another writer keeps changing under it."""
APPLIED_KEEP_DAYS = 30
"""How long a write's id is kept in ``applied_writes``: longer than any spool waits."""
PRUNE_EVERY = 1000
"""Writes with an id between two prunings of old ids, per store."""

T = TypeVar("T")


def _one_line(error: BaseException) -> str:
    text = str(getattr(error, "orig", None) or error).strip().splitlines()
    return text[0] if text else type(error).__name__


_TRANSIENT_SQLSTATE_CLASSES = ("08", "40", "53", "57", "58", "HY", "XX")
"""PostgreSQL error classes that pass: connection, rollback (serialization, deadlock),
resources, operator intervention (shutdown, statement timeout), system, internal."""
_TRANSIENT_SQLSTATES = frozenset({"55P03", "55006"})  # lock not available, object in use
_PERMANENT_SQLITE = ("no such table", "no such column", "has no column", "constraint failed")


def classify(error: SQLAlchemyError) -> StoreUnavailable | StoreRefused:
    """A database error as a passing trouble (retry later) or a refusal of this request.

    When in doubt it is passing: a write kept for a retry is never lost, one refused is
    set aside for good.
    """
    line = f"database error: {_one_line(error)}"
    if not isinstance(error, DBAPIError):
        if isinstance(error, PoolTimeout | DisconnectionError):
            return StoreUnavailable(line)
        return StoreRefused(line)  # bad data caught before the database (a bind, a type)
    if error.connection_invalidated or isinstance(error, InterfaceError):
        return StoreUnavailable(line)
    sqlstate = getattr(error.orig, "sqlstate", None)
    if isinstance(sqlstate, str) and len(sqlstate) == 5:
        transient = sqlstate in _TRANSIENT_SQLSTATES or sqlstate.startswith(
            _TRANSIENT_SQLSTATE_CLASSES
        )
        return StoreUnavailable(line) if transient else StoreRefused(line)
    if isinstance(error, OperationalError):
        text = str(error.orig).lower()
        if any(part in text for part in _PERMANENT_SQLITE):
            return StoreRefused(line)
        return StoreUnavailable(line)  # locked, busy, disk I/O, cannot open, disk full
    if type(error) in (DBAPIError, DatabaseError) or isinstance(error, InternalError):
        return StoreUnavailable(line)  # no finer class (a damaged file, a driver fault)
    return StoreRefused(line)  # integrity, data, programming, not supported


def _check_time(name: str, value: Any) -> datetime:
    if not isinstance(value, datetime) or value.tzinfo is None:
        raise ProfileError(f"{name}: must be a tz-aware UTC datetime (got {value!r:.60})")
    return value


def _check_metrics(metrics: Any) -> None:
    """A session's metrics: a dict of names to finite numbers or None, nothing else
    (they are stored as JSON and read back by ``dms sessions``)."""
    if not isinstance(metrics, dict):
        raise ProfileError(f"metrics: must be a dict (got {metrics!r:.60})")
    for key, value in metrics.items():
        number = isinstance(value, int | float) and not isinstance(value, bool)
        if not isinstance(key, str) or not (value is None or (number and math.isfinite(value))):
            raise ProfileError(f"metrics: {key!r:.40} must be a finite number or null")


def _check_user_id(user_id: Any) -> str:
    """The id rule of the bus (:mod:`dms.kernel.ids`), already trimmed: a store never renames."""
    try:
        trimmed = check_identifier(user_id, "user_id")
    except InvalidIdentifier as error:
        raise ProfileError(str(error)) from None
    if trimmed != user_id:
        raise ProfileError(f"user_id: has white space around it (got {user_id!r:.60})")
    return trimmed


def _check_name(field: str, value: Any, max_length: int = 50) -> str:
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
_USER_COLUMNS = tuple(column.key for column in USERS.columns)
_COUNTERS = ("feedback_sum", "feedback_count", "completions", "cancellations")


@dataclass
class _UserFields:
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


def _profile(row: UserRow | _UserFields, scores: dict[str, ActivityScore]) -> Profile:
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
    return _profile(
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


# Core statements of the write path, built once (issue 14: the ORM's unit of work was
# nine tenths of a profile write). SQLAlchemy caches their compiled form by statement.


def _load_statement(lock: bool) -> Select[Any]:
    """The user joined with their scores, as the ORM's joined load read them; ``lock``:
    ``FOR UPDATE OF users`` (PostgreSQL's field writes)."""
    statement = (
        select(
            *USERS.columns,
            *(SCORES.c[name].label(f"score_{name}") for name in ("activity", *_COUNTERS)),
        )
        .select_from(USERS.outerjoin(SCORES, USERS.c.user_id == SCORES.c.user_id))
        .where(USERS.c.user_id == bindparam("key_user_id"))
    )
    return statement.with_for_update(of=USERS) if lock else statement


_LOAD = _load_statement(lock=False)
_LOAD_FOR_UPDATE = _load_statement(lock=True)
_USER_EXISTS = select(USERS.c.user_id).where(USERS.c.user_id == bindparam("key_user_id"))
_SESSION_EXISTS = select(SESSIONS.c.id).where(SESSIONS.c.id == bindparam("key_id"))
_TOUCH = (
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
_WRITE_FIELDS = update(USERS).where(
    USERS.c.user_id == bindparam("key_user_id"), USERS.c.version == bindparam("key_version")
)
"""Set the columns given as parameters if the version is still the one read (the
ORM's ``version_id_col`` check, by hand)."""
_END_SESSION = update(SESSIONS).where(SESSIONS.c.id == bindparam("key_id"))
_INSERT_USER = insert(USERS)
_INSERT_SESSION = insert(SESSIONS)
_INSERT_RUN = insert(RUNS)
_INSERT_FEEDBACK = insert(FEEDBACK)
_INSERT_ANSWER = insert(ANSWERS)
_INSERT_APPLIED = insert(APPLIED)
_APPLIED_RESULT = select(APPLIED.c.result).where(APPLIED.c.write_id == bindparam("key_write_id"))


def _upserts(dialect: str) -> tuple[Executable, Executable] | None:
    """The dialect's (score upsert, user insert-if-missing), None without upserts.

    The score upsert adds all four counters (``n = n + excluded.n``); a counter the write
    does not move is added 0, which leaves it as it was."""
    if dialect not in ("sqlite", "postgresql"):
        return None
    module: Any = sqlite if dialect == "sqlite" else postgresql
    bump = module.insert(SCORES)
    return (
        bump.on_conflict_do_update(
            index_elements=["user_id", "activity"],
            set_={name: SCORES.c[name] + bump.excluded[name] for name in _COUNTERS},
        ),
        module.insert(USERS).on_conflict_do_nothing(index_elements=["user_id"]),
    )


def _load(
    connection: Connection, user_id: str, lock: bool = False
) -> tuple[RowMapping, dict[str, ActivityScore]]:
    """The user's columns and scores; ProfileNotFound without the user."""
    rows = connection.execute(_LOAD_FOR_UPDATE if lock else _LOAD, {"key_user_id": user_id}).all()
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


def _fields(columns: RowMapping) -> _UserFields:
    return _UserFields(**{name: columns[name] for name in _USER_COLUMNS})


class UserData(Protocol):
    """Rows about users that another package keeps in the same database (the agenda).

    Registered with :func:`register_user_data` so that :meth:`ProfileStore.export` and
    :meth:`ProfileStore.erase` cover them too, in the same transaction, without the
    memory package importing the other one.
    """

    name: str
    """The key of this part in the export."""

    def export_user(self, session: Session, user_id: str) -> Any | None:
        """Everything this part stores about ``user_id``, JSON-able; None if it has no tables."""
        ...

    def erase_user(self, session: Session, user_id: str) -> None:
        """Delete every row this part stores about ``user_id``."""
        ...


_USER_DATA: dict[str, UserData] = {}


def register_user_data(part: UserData) -> None:
    """Add ``part`` to every export and erase (called when its package is imported)."""
    _USER_DATA[part.name] = part


class _Conflict(StoreRefused):
    """A write collided with a row another writer made (a unique key)."""


class _Stale(StoreUnavailable):
    """Another writer changed the row since this write read it (its version moved)."""


@contextmanager
def _classified() -> Iterator[None]:
    """Database failures inside become StoreUnavailable or StoreRefused (:func:`classify`),
    a row changed under an ORM write :class:`_Stale`, a key collision :class:`_Conflict`;
    the store's own errors pass as they are."""
    try:
        yield
    except ProfileError:
        raise
    except StaleDataError as error:
        raise _Stale(f"changed by another writer: {_one_line(error)}") from None
    except IntegrityError as error:
        raise _Conflict(f"refused by the database: {_one_line(error)}") from None
    except SQLAlchemyError as error:
        raise classify(error) from None


class ProfileStore:
    """Profiles and their history in the database at ``url``.

    Raises:
        ProfileError: the database cannot be opened (one-line message).
        SchemaOutOfDate: the database needs ``dms db upgrade --db URL``.
    """

    def __init__(self, url: str | None = None, busy_timeout_s: float | None = None) -> None:
        self.url = as_url(url) if url else default_url()
        try:
            shown = make_url(self.url).render_as_string(hide_password=True)
        except ArgumentError as error:
            raise ProfileError(f"cannot open database {self.url!r}: {error}") from None
        try:
            self.engine = make_engine(self.url, busy_timeout_s)
            with self.engine.connect() as connection:
                installed = migrations.installed(connection)
                current = migrations.current(connection) if installed else None
                tables = set(inspect(connection).get_table_names())
        except (SQLAlchemyError, OSError, ImportError) as error:
            raise ProfileError(f"cannot open database {shown}: {_one_line(error)}") from None
        head = migrations.head()
        if not installed:
            try:
                migrations.upgrade_engine(self.engine)
            except SQLAlchemyError as error:
                self.engine.dispose()
                raise ProfileError(
                    f"cannot create the profile tables in {shown}: {_one_line(error)}"
                ) from None
        elif current != head:
            self.engine.dispose()
            raise SchemaOutOfDate(
                f"database {shown} has profile schema {current or 'unversioned'}, "
                f"this dms needs {head}: run `dms db upgrade --db {shown}`"
            )
        elif missing := [name for name in migrations.TABLES if name not in tables]:
            self.engine.dispose()
            raise StoreDamaged(
                f"database {shown} is damaged: table {', '.join(missing)} missing at schema "
                f"{head}; restore a backup, or run `dms db upgrade --db {shown}` to recreate "
                "it empty"
            )
        self._sessions = sessionmaker(self.engine, expire_on_commit=False)
        self._read_engine = self.engine.execution_options(isolation_level="AUTOCOMMIT")
        """For one-statement reads: no BEGIN and COMMIT round trips (a profile load is one
        SELECT of the user joined with their scores, consistent by itself)."""
        self._reads = sessionmaker(self._read_engine, expire_on_commit=False)
        self._dialect = self.engine.dialect.name
        self._upserts = _upserts(self._dialect)
        self._count_lock = threading.Lock()
        self._since_prune = 0
        self.retries = 0
        """Field writes retried because another writer changed the row first."""
        self.after_field_read: Callable[[], None] | None = None
        """Called inside a field write between reading the user's row and writing it: a
        seam where the fleet's tests put another robot's write (the race the version
        check and, on PostgreSQL, the row lock resolve). None in use."""

    # ------------------------------------------------------------------ plumbing

    @contextmanager
    def _read(self) -> Iterator[Session]:
        """One read outside any transaction, through an ORM session (errors classified:
        :func:`_classified`)."""
        with _classified(), self._reads() as session:
            yield session

    @contextmanager
    def _read_connection(self) -> Iterator[Connection]:
        """:meth:`_read` without an ORM session, for Core statements."""
        with _classified(), self._read_engine.connect() as connection:
            yield connection

    @contextmanager
    def _session(self) -> Iterator[Session]:
        """One short transaction through an ORM session, for what reads or deletes
        mapped rows (export, erase, listings); errors classified (:func:`_classified`)."""
        with _classified(), self._sessions.begin() as session:
            yield session

    @contextmanager
    def _transaction(self) -> Iterator[Connection]:
        """One short transaction on a plain connection, for the writes: they run Core
        statements, and an ORM session's own bookkeeping was a quarter of a profile
        write's time (issue 14). Errors classified (:func:`_classified`)."""
        with _classified(), self.engine.begin() as connection:
            yield connection

    @staticmethod
    def _user(session: Session, user_id: str) -> UserRow:
        row = session.get(UserRow, user_id)
        if row is None:
            raise ProfileNotFound(f"no profile for user {user_id!r}")
        return row

    @staticmethod
    def _check_user(connection: Connection, user_id: str) -> None:
        if connection.execute(_USER_EXISTS, {"key_user_id": user_id}).first() is None:
            raise ProfileNotFound(f"no profile for user {user_id!r}")

    def _bump_score(
        self, connection: Connection, user_id: str, activity: str, **deltas: float
    ) -> None:
        """Add ``deltas`` to the user's score of ``activity`` in the database, creating the
        row if needed: one statement, so concurrent writers neither collide nor lose one."""
        values: dict[str, Any] = {
            "user_id": user_id,
            "activity": activity,
            "feedback_sum": 0.0,
            "feedback_count": 0,
            "completions": 0,
            "cancellations": 0,
            **deltas,
        }
        if self._upserts is not None:
            connection.execute(self._upserts[0], values)
            return
        changed = connection.execute(
            update(SCORES)
            .where(SCORES.c.user_id == user_id, SCORES.c.activity == activity)
            .values({name: SCORES.c[name] + value for name, value in deltas.items()})
        )
        if not changed.rowcount:
            connection.execute(insert(SCORES), values)

    @staticmethod
    def _touch(connection: Connection, user_id: str, when: datetime) -> None:
        """Bump the user's version and move ``updated_at`` up to ``when`` (never back),
        in the database; ProfileNotFound without the user. Locks the row (PostgreSQL)
        until the transaction ends, so the writes of one user queue there."""
        changed = connection.execute(_TOUCH, {"key_user_id": user_id, "key_when": when})
        if not changed.rowcount:
            raise ProfileNotFound(f"no profile for user {user_id!r}")

    @staticmethod
    def _fresh(connection: Connection, user_id: str) -> Profile:
        """The user's snapshot as this transaction sees it now (after its own writes)."""
        columns, scores = _load(connection, user_id)
        return _profile(_fields(columns), scores)

    def _once(
        self,
        write_id: str | None,
        user_id: str,
        change: Callable[[Connection], T],
        again: Callable[[int | None], T],
        result: Callable[[T], int | None] = lambda _: None,
    ) -> T:
        """Run ``change`` in one transaction, once per ``write_id``, retried while another
        writer changes the row under it (:class:`_Stale`).

        With a ``write_id`` the write is recorded in ``applied_writes`` in the same
        transaction; a write whose id is there already fails on the key (the insert
        comes last), so it is rolled back whole (a replay costs one wasted transaction,
        a first run no extra read): ``again`` answers with what the first run stored
        (``result`` of its answer).
        """
        if write_id is not None and (not isinstance(write_id, str) or not 0 < len(write_id) <= 64):
            raise ProfileError(
                f"write_id: must be a string of 1 to 64 characters (got {write_id!r:.60})"
            )
        for attempt in range(MAX_ATTEMPTS):
            try:
                with self._transaction() as connection:
                    answer = change(connection)
                    if write_id is not None:
                        connection.execute(
                            _INSERT_APPLIED,
                            {
                                "write_id": write_id,
                                "user_id": user_id,
                                "result": result(answer),
                                "applied_at": datetime.now(UTC),
                            },
                        )
                self._count_write(write_id)
                return answer
            except _Stale:
                with self._count_lock:
                    self.retries += 1
                # Out of step with the other writer before the next try: a jittered,
                # growing pause (at most 50 ms), so that two robots do not collide again.
                time.sleep(random.uniform(0, min(0.05, 0.001 * 2 ** min(attempt, 6))))
                continue
            except _Conflict:
                # The write's id is in applied_writes: it was applied before (a replay),
                # or by a run of it at the same time (a writer stuck in flight).
                if write_id is not None:
                    stored = self._applied(write_id)
                    if stored is not None:
                        return again(stored[0])
                raise
        raise StoreUnavailable(
            f"the profile of {user_id!r} kept changing under {MAX_ATTEMPTS} tries; retry later"
        )

    def _applied(self, write_id: str) -> tuple[int | None] | None:
        with self._read_connection() as connection:
            row = connection.execute(_APPLIED_RESULT, {"key_write_id": write_id}).first()
            return None if row is None else (row[0],)

    def _count_write(self, write_id: str | None) -> None:
        if write_id is None:
            return
        with self._count_lock:
            self._since_prune += 1
            due = self._since_prune >= PRUNE_EVERY
            if due:
                self._since_prune = 0
        if due:
            with suppress(ProfileError):  # the next prune will do
                self.prune_applied(datetime.now(UTC) - timedelta(days=APPLIED_KEEP_DAYS))

    def prune_applied(self, before: datetime) -> int:
        """Forget the ids of writes applied before ``before``; how many went."""
        _check_time("before", before)
        with self._transaction() as connection:
            gone = connection.execute(
                delete(AppliedWriteRow).where(AppliedWriteRow.applied_at < before)
            )
            return int(gone.rowcount)

    def _field_write(
        self,
        write_id: str | None,
        user_id: str,
        change: Callable[[_UserFields], None],
        also: Callable[[Connection], None] | None = None,
    ) -> Profile:
        """A read-modify-write of the user's row: ``change`` edits the row as read (on
        PostgreSQL locked, ``SELECT ... FOR UPDATE``, so the other robots' writes of
        this user wait instead of failing their version check); the columns it changed
        are written only if the row's version is still the one read, else it is run again
        on the fresh row. ``also`` adds rows in the same transaction (an answer).

        Nothing changed, nothing is written and the version stays (as the ORM did)."""

        def run(connection: Connection) -> Profile:
            columns, scores = _load(connection, user_id, lock=self._dialect == "postgresql")
            row = _fields(columns)
            change(row)
            changed = {
                name: value
                for name in _USER_COLUMNS
                if (value := getattr(row, name)) != columns[name]
            }
            if self.after_field_read is not None:
                self.after_field_read()
            if also is not None:
                also(connection)
            if changed:
                row.version = columns["version"] + 1
                written = connection.execute(
                    _WRITE_FIELDS,
                    {
                        **changed,
                        "version": row.version,
                        "key_user_id": user_id,
                        "key_version": columns["version"],
                    },
                )
                if written.rowcount != 1:
                    raise _Stale(f"changed by another writer: the profile of {user_id!r}")
            return _profile(row, scores)

        return self._once(write_id, user_id, run, lambda _: self.get(user_id))

    # ------------------------------------------------------------------ profiles

    def get_or_create(self, user_id: str, now: datetime) -> Profile:
        """Step 5: the user's profile, or a new empty one for a new user.

        Two robots meeting a new user at once make one profile (the second insert is a
        no-op in the database)."""
        _check_user_id(user_id)
        _check_time("now", now)
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
                    connection.execute(_INSERT_USER, values)
                return self._fresh(connection, user_id)
        except _Conflict:
            pass
        # Another writer created it between our read and our insert.
        return self.get(user_id)

    def last_run(self, user_id: str) -> dict[str, Any] | None:
        """The user's latest activity run at any robot of the fleet (``activity``,
        ``ended``, ``outcome``, ``chosen_by``), None if there is none: a robot that
        meets her reads it to resume what another robot's session end cut."""
        _check_user_id(user_id)
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

    def get(self, user_id: str) -> Profile:
        """The user's profile; ProfileNotFound if there is none."""
        with self._read_connection() as connection:
            return self._fresh(connection, user_id)

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
        _check_time("now", now)
        columns, attributes = validate_fields(fields)

        def change(row: _UserFields) -> None:
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
            }
            for part in _USER_DATA.values():
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
            for part in _USER_DATA.values():
                part.erase_user(session, user_id)
            # Explicit deletes, children first: no reliance on the backend's cascade.
            for model in (
                AppliedWriteRow,
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
        _check_time("now", now)

        def change(connection: Connection) -> int:
            self._check_user(connection, user_id)
            inserted = connection.execute(_INSERT_SESSION, {"user_id": user_id, "started_at": now})
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
        _check_time("now", now)
        if metrics is not None:
            _check_metrics(metrics)
        values: dict[str, Any] = {"ended_at": now, "key_id": session_id}
        if metrics is not None:
            values["metrics"] = dict(metrics)
        with self._transaction() as connection:
            if connection.execute(_SESSION_EXISTS, {"key_id": session_id}).first() is None:
                raise ProfileError(f"session_id: no session {session_id!r}")
            connection.execute(_END_SESSION, values)

    def sessions(self, since: datetime | None = None) -> list[dict[str, Any]]:
        """Every session (of every user) started at or after ``since``, oldest first:
        ``{"session", "user", "started", "ended", "metrics"}`` (times as ISO strings,
        ``ended`` and ``metrics`` None while a session is open or was stored without).
        For ``dms sessions``: a deployment's own Table 4."""
        if since is not None:
            _check_time("since", since)
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
        _check_name("activity", activity)
        _check_time("started", started)
        _check_time("ended", ended)
        _check_name("outcome", outcome)
        _check_name("chosen_by", chosen_by, 20)
        if not isinstance(cancelled, bool):
            raise ProfileError(f"cancelled: must be true or false (got {cancelled!r:.60})")
        if ended < started:
            raise ProfileError("ended: is before started")

        def change(connection: Connection) -> Profile:
            self._touch(connection, user_id, ended)
            if (
                session_id is not None
                and connection.execute(_SESSION_EXISTS, {"key_id": session_id}).first() is None
            ):
                raise ProfileError(f"session_id: no session {session_id!r}")
            connection.execute(
                _INSERT_RUN,
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
        _check_name("activity", activity)
        _check_time("now", now)
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
                _INSERT_FEEDBACK,
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

        _check_name("question_id", question_id, 100)
        _check_time("now", now)
        if not isinstance(answer, str) or len(answer) > 2000:
            raise ProfileError("answer: must be a string of at most 2000 characters")
        bank = QuestionBank.default()
        question = bank.get(question_id)
        applied = bank.parse(question, answer) if question is not None else None
        columns, attributes = validate_fields(applied or {})

        def change(row: _UserFields) -> None:
            for name, value in columns.items():
                setattr(row, name, value)
            if attributes:
                row.attributes = {**(row.attributes or {}), **attributes}
            if "robot_initiative_frequency" in columns:  # seeds the proactivity estimate
                self._estimate_proactivity(row)
            row.updated_at = now

        def log(connection: Connection) -> None:
            connection.execute(
                _INSERT_ANSWER,
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
    def _estimate_proactivity(row: _UserFields) -> None:
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
        _check_time("now", now)
        attribute = f"{channel}_failures"

        def change(row: _UserFields) -> None:
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
        _check_time("now", now)

        def change(row: _UserFields) -> None:
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

    def close(self) -> None:
        """Release the connections (the data is already committed)."""
        self.engine.dispose()
