"""The profile store's database: opening it, and how every read and write runs.

At open the schema is created in a new database or checked (:class:`SchemaOutOfDate`,
:class:`StoreDamaged`). A read runs on a connection that commits nothing; a write runs
in one short transaction on a plain connection (:meth:`_transaction`).

Several robots may write one profile at once (docs/fleet.md). :meth:`_once` applies a
write once per ``write_id`` (recorded in ``applied_writes`` in the same transaction, so
a spool replayed after a crash skips it) and retries it while another writer changes
the row under it; :meth:`_field_write` writes the user's fields through the row's
version (``users.version``: the UPDATE names the version read), so a write made on a
stale read is run again on the fresh row instead of overwriting it.
"""

from __future__ import annotations

import random
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress
from datetime import UTC, datetime, timedelta
from typing import Any, TypeVar

from sqlalchemy import Connection, delete, insert, update
from sqlalchemy.exc import SQLAlchemyError
from sqlalchemy.orm import Session, sessionmaker

from memory import migrations
from memory.db import as_url, default_url, shown_url
from memory.errors import ProfileError, ProfileNotFound, StoreUnavailable, one_line
from memory.failures import Conflict, Stale, classified
from memory.models import AppliedWriteRow, UserRow
from memory.profile import Profile
from memory.rows import (
    APPLIED_RESULT,
    INSERT_APPLIED,
    SCORES,
    TOUCH,
    USER_COLUMNS,
    USER_EXISTS,
    WRITE_FIELDS,
    UserFields,
    check_time,
    fields_of,
    load_user,
    profile_of,
    upserts,
)

MAX_ATTEMPTS = 50
"""Tries of one field write whose row another writer keeps changing under it."""
APPLIED_KEEP_DAYS = 30
"""How long a write's id is kept in ``applied_writes``: longer than any spool waits."""
PRUNE_EVERY = 1000
"""Writes with an id between two prunings of old ids, per store."""

T = TypeVar("T")


class StoreDatabase:
    """The profile store's database at ``url``: opened and checked, read and written in
    short transactions; :class:`memory.store.ProfileStore` builds on it.

    Raises:
        ProfileError: the database cannot be opened (one-line message), or a newer dms
            wrote it.
        SchemaOutOfDate: the database needs ``dms db upgrade --db URL``.
    """

    def __init__(self, url: str | None = None, busy_timeout_s: float | None = None) -> None:
        self.url = as_url(url) if url else default_url()
        self.engine, new = migrations.open_checked(self.url, busy_timeout_s)
        if new:
            try:
                migrations.upgrade_engine(self.engine)
            except SQLAlchemyError as error:
                self.engine.dispose()
                shown = shown_url(self.url)
                raise ProfileError(
                    f"cannot create the profile tables in {shown}: {one_line(error)}"
                ) from None
        self._sessions = sessionmaker(self.engine, expire_on_commit=False)
        self._dialect = self.engine.dialect.name
        self._upserts = upserts(self._dialect)
        self._count_lock = threading.Lock()
        self._since_prune = 0
        self.retries = 0
        """Field writes retried because another writer changed the row first."""
        self.after_field_read: Callable[[], None] | None = None
        """Called inside a field write between reading the user's row and writing it: a
        seam where the fleet's tests put another robot's write (the race the version
        check and, on PostgreSQL, the row lock resolve). None in use."""

    @contextmanager
    def _read(self) -> Iterator[Session]:
        """One read through an ORM session, which commits nothing (errors classified:
        :func:`classified`)."""
        with classified(), self._sessions() as session:
            yield session

    @contextmanager
    def _read_connection(self) -> Iterator[Connection]:
        """:meth:`_read` without an ORM session, for Core statements."""
        with classified(), self.engine.connect() as connection:
            yield connection

    @contextmanager
    def _session(self) -> Iterator[Session]:
        """One short transaction through an ORM session, for what reads or deletes
        mapped rows (export, erase, listings); errors classified (:func:`classified`)."""
        with classified(), self._sessions.begin() as session:
            yield session

    @contextmanager
    def _transaction(self) -> Iterator[Connection]:
        """One short transaction on a plain connection, for the writes: they run Core
        statements (:mod:`memory.rows`), and an ORM session's own bookkeeping was a
        quarter of a profile write's time. Errors classified (:func:`classified`)."""
        with classified(), self.engine.begin() as connection:
            yield connection

    @staticmethod
    def _user(session: Session, user_id: str) -> UserRow:
        row = session.get(UserRow, user_id)
        if row is None:
            raise ProfileNotFound(f"no profile for user {user_id!r}")
        return row

    @staticmethod
    def _check_user(connection: Connection, user_id: str) -> None:
        if connection.execute(USER_EXISTS, {"key_user_id": user_id}).first() is None:
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
        changed = connection.execute(TOUCH, {"key_user_id": user_id, "key_when": when})
        if not changed.rowcount:
            raise ProfileNotFound(f"no profile for user {user_id!r}")

    @staticmethod
    def _fresh(connection: Connection, user_id: str) -> Profile:
        """The user's snapshot as this transaction sees it now (after its own writes)."""
        columns, scores = load_user(connection, user_id)
        return profile_of(fields_of(columns), scores)

    def _once(
        self,
        write_id: str | None,
        user_id: str,
        change: Callable[[Connection], T],
        again: Callable[[int | None], T],
        result: Callable[[T], int | None] = lambda _: None,
    ) -> T:
        """Run ``change`` in one transaction, once per ``write_id``, retried while another
        writer changes the row under it (:class:`Stale`).

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
                            INSERT_APPLIED,
                            {
                                "write_id": write_id,
                                "user_id": user_id,
                                "result": result(answer),
                                "applied_at": datetime.now(UTC),
                            },
                        )
                self._count_write(write_id)
                return answer
            except Stale:
                with self._count_lock:
                    self.retries += 1
                # Out of step with the other writer before the next try: a jittered,
                # growing pause (at most 50 ms), so that two robots do not collide again.
                time.sleep(random.uniform(0, min(0.05, 0.001 * 2 ** min(attempt, 6))))
                continue
            except Conflict:
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
            row = connection.execute(APPLIED_RESULT, {"key_write_id": write_id}).first()
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
        check_time("before", before)
        with self._transaction() as connection:
            gone = connection.execute(
                delete(AppliedWriteRow).where(AppliedWriteRow.applied_at < before)
            )
            return int(gone.rowcount)

    def _field_write(
        self,
        write_id: str | None,
        user_id: str,
        change: Callable[[UserFields], None],
        also: Callable[[Connection], None] | None = None,
    ) -> Profile:
        """A read-modify-write of the user's row: ``change`` edits the row as read (on
        PostgreSQL locked, ``SELECT ... FOR UPDATE``, so the other robots' writes of
        this user wait instead of failing their version check); the columns it changed
        are written only if the row's version is still the one read, else it is run again
        on the fresh row. ``also`` adds rows in the same transaction (an answer).

        Nothing changed, nothing is written and the version stays (as the ORM did)."""

        def run(connection: Connection) -> Profile:
            columns, scores = load_user(connection, user_id, lock=self._dialect == "postgresql")
            row = fields_of(columns)
            change(row)
            changed = {
                name: value
                for name in USER_COLUMNS
                if (value := getattr(row, name)) != columns[name]
            }
            if self.after_field_read is not None:
                self.after_field_read()
            if also is not None:
                also(connection)
            if changed:
                row.version = columns["version"] + 1
                written = connection.execute(
                    WRITE_FIELDS,
                    {
                        **changed,
                        "version": row.version,
                        "key_user_id": user_id,
                        "key_version": columns["version"],
                    },
                )
                if written.rowcount != 1:
                    raise Stale(f"changed by another writer: the profile of {user_id!r}")
            return profile_of(row, scores)

        return self._once(write_id, user_id, run, lambda _: self.get(user_id))

    def get(self, user_id: str) -> Profile:
        """The user's profile; ProfileNotFound if there is none."""
        with self._read_connection() as connection:
            return self._fresh(connection, user_id)

    def close(self) -> None:
        """Release the connections (the data is already committed)."""
        self.engine.dispose()
