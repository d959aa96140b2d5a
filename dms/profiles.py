"""The controller's view of the profile store: cached snapshots, writes off the tick.

The decision loop must keep deciding whatever the database does. Every profile read
and write goes through a :class:`dms.storage.StorageWriter`: a writer thread in the
daemon (the tick never waits on the database), inline in the simulator (a seeded run
stays deterministic). Results refresh a cache of profile snapshots that the controller
reads. A write the database cannot take now is spooled to a durable file and replayed
in order; one it refuses for good is quarantined with a report (``report``: the daemon
publishes it on ``dms/errors``). A session is named by a key made here, so that the
controller need not wait for the database's id.

Every write gets a unique ``write_id`` here, spooled with it: the store records it in
the write's own transaction and skips a write whose id it has (docs/fleet.md), so a
replay after a crash, or the write that was in flight when the writer gave up, is
applied once. A session's key is its ``start_session``'s id.
"""

from __future__ import annotations

import logging
import threading
import uuid
from collections.abc import Callable, Mapping, Sequence
from datetime import datetime
from pathlib import Path
from typing import Any

from dms.storage import (
    QUEUE_SIZE,
    RETRY_EVERY_S,
    StorageWriter,
    StoreOp,
    Waiter,
    Write,
    sqlite_file,
)
from memory import Profile, ProfileStore
from memory.backlog import MEMORY_BOUND
from memory.db import side_file
from memory.errors import ProfileNotFound, StoreRefused

__all__ = ["LOAD_WAIT_S", "RETRY_EVERY_S", "ProfileService"]

log = logging.getLogger(__name__)

LOAD_WAIT_S = 0.05
"""How long :meth:`ProfileService.load` waits for a profile read off the tick: long
enough for a healthy database, so the session starts with the profile in the same tick;
short enough that a locked or absent database costs the tick nothing noticeable."""

_RECORD_ACTIVITY_SESSION = 7  # the position of session_id in ProfileStore.record_activity


class ProfileService:
    """Profile loads and writes for the controller; none waits on the database."""

    def __init__(
        self,
        store: ProfileStore,
        report: Callable[[str, str], None],
        *,
        threaded: bool = True,
        queue_size: int = QUEUE_SIZE,
        spool_path: Path | None = None,
        quarantine_path: Path | None = None,
        owner: str | None = None,
        spool_dir: Path | None = None,
        memory_bound: int = MEMORY_BOUND,
    ) -> None:
        """``owner``: the robot id, so that robots sharing a database on one machine keep
        their own spool and quarantine files (:func:`memory.db.side_file`).
        ``spool_dir``, ``memory_bound``: where writes wait when the spool beside the
        database cannot be written (``[storage]``, :class:`dms.storage.StorageWriter`)."""
        self.store = store
        self._cache: dict[str, Profile] = {}
        self._cache_lock = threading.Lock()
        self._met: set[str] = set()
        self.newcomer: str | None = None
        """The user in front of the robot whose profile is not stored yet (the controller
        stores it once she qualifies): met, so the agenda takes items for her."""
        self.writer = StorageWriter(
            self._apply,
            spool_path or side_file(store.url, "spool", owner),
            quarantine_path or side_file(store.url, "quarantine", owner),
            report,
            self._done,
            threaded=threaded,
            queue_size=queue_size,
            spool_dir=spool_dir,
            memory_bound=memory_bound,
            database_file=sqlite_file(store.url),
        )
        self.writer.start()

    def load(self, user_id: str, now: datetime, wait_s: float = LOAD_WAIT_S) -> Profile | None:
        """Read (or create) ``user_id``'s profile off the tick, waiting at most ``wait_s``.

        Returns the profile, or meanwhile the cached one (None for a user never loaded);
        the cache is refreshed when the read lands.
        """
        with self._cache_lock:
            self._met.add(user_id)
        profile = self._read(Write("get_or_create", (user_id, now)), wait_s)
        return profile if isinstance(profile, Profile) else self.cached(user_id)

    def _read(self, write: Write, wait_s: float) -> Any:
        """A store read, in order behind the writes queued before it, waiting at most
        ``wait_s``: its result, or None when it has not landed by then."""
        waiter = Waiter()
        self.writer.submit(write, waiter)
        waiter.wait(wait_s)
        return waiter.result

    def stored(self, user_id: str, wait_s: float = LOAD_WAIT_S) -> bool | None:
        """Whether the store has a profile for ``user_id`` (read off the tick, in order
        behind the writes queued before it); None when the read has not landed in time."""
        found = self._read(Write("find", (user_id,)), wait_s)
        return found if isinstance(found, bool) else None

    def meet_newcomer(self, user_id: str | None) -> None:
        """``user_id`` is in front of the robot, not stored yet (None: nobody is): the
        agenda takes items for her meanwhile (:meth:`met`)."""
        self.newcomer = user_id

    def last_run(self, user_id: str, wait_s: float = LOAD_WAIT_S) -> dict[str, Any] | None:
        """The user's last activity run (:meth:`memory.ProfileStore.last_run`), read off
        the tick; None when there is none or the read has not landed in time."""
        found = self._read(Write("last_run", (user_id,)), wait_s)
        return found if isinstance(found, dict) else None

    def met(self, user_id: str) -> bool:
        """The robot has met ``user_id`` in this run: their profile exists, or is being
        written, or they are in front of the robot not yet stored (:attr:`newcomer`); the
        agenda accepts items for them before the write lands."""
        if user_id == self.newcomer:
            return True
        with self._cache_lock:
            return user_id in self._met or user_id in self._cache

    def cached(self, user_id: str) -> Profile | None:
        with self._cache_lock:
            return self._cache.get(user_id)

    # ------------------------------------------------------------------ the writes
    # Each queues one store call and returns at once. Each gets a ``write_id``, spooled
    # with it, so that a replay applies it once (the module's docstring).

    def start_session(self, user_id: str, now: datetime) -> str:
        """Open a session; returns its key, which stands for the session's id in later
        writes (:meth:`end_session`, :meth:`record_activity`), also after a restart when
        they were spooled."""
        key = f"session-{uuid.uuid4().hex}"
        self.writer.submit(Write("start_session", (user_id, now), {"key": key}))
        return key

    def end_session(
        self, session: str | int, now: datetime, metrics: Mapping[str, Any] | None = None
    ) -> None:
        """Close the session ``session`` (its key, or its id) with its Table 4 metrics."""
        extra = {} if metrics is None else {"metrics": dict(metrics)}
        self.writer.submit(Write("end_session", (session, now), extra))

    def update(self, user_id: str, now: datetime, **fields: Any) -> None:
        """Set profile fields or attributes (:meth:`memory.ProfileStore.update`)."""
        self._once("update", (user_id, now), fields)

    def record_activity(
        self,
        user_id: str,
        activity: str,
        started: datetime,
        ended: datetime,
        outcome: str,
        chosen_by: str,
        cancelled: bool,
        session: str | int | None = None,
    ) -> None:
        """One activity run, in ``session`` (its key, or its id) when there is one."""
        self._once(
            "record_activity",
            (user_id, activity, started, ended, outcome, chosen_by, cancelled, session),
        )

    def record_feedback(self, user_id: str, activity: str, score: float, now: datetime) -> None:
        """The user's rating of ``activity``, 0..1."""
        self._once("record_feedback", (user_id, activity, score, now))

    def record_answer(self, user_id: str, question_id: str, answer: str, now: datetime) -> None:
        """The user's answer to a general question."""
        self._once("record_answer", (user_id, question_id, answer, now))

    def record_interaction(self, user_id: str, channel: str, answered: bool, now: datetime) -> None:
        """Whether the user answered a prompt on ``channel`` (voice or screen)."""
        self._once("record_interaction", (user_id, channel, answered, now))

    def record_initiative(self, user_id: str, took_initiative: bool, now: datetime) -> None:
        """Whether the user took the initiative when offered it (proactivity)."""
        self._once("record_initiative", (user_id, took_initiative, now))

    def record_interactions(
        self, user_id: str, session: str | int | None, events: Sequence[Mapping[str, Any]]
    ) -> None:
        """Interaction events of ``session`` (its key, or its id) (:mod:`memory.interactions`)."""
        self._once("record_interactions", (user_id, session, [dict(e) for e in events]))

    def _once(self, op: StoreOp, args: tuple[Any, ...], kwargs: Mapping[str, Any] = {}) -> None:
        self.writer.submit(Write(op, args, {**kwargs, "write_id": uuid.uuid4().hex}))

    def retry(self, now: datetime) -> None:
        """Called every tick: without a writer thread, replay the spool when due."""
        self.writer.poll(now.timestamp())

    @property
    def pending_writes(self) -> int:
        """Writes not yet in the database (queued, in flight or spooled)."""
        return self.writer.pending

    def close(self) -> int:
        """Finish or spool what is queued; returns how many writes stay spooled (reported)."""
        return self.writer.close()

    # ------------------------------------------------------------------ the writer's side

    def _apply(self, write: Write) -> Any:
        """Run one write against the store (the writer's thread)."""
        args, kwargs = list(write.args), dict(write.kwargs)
        if write.method == "find":
            try:
                return self.store.get(str(args[0])) is not None
            except ProfileNotFound:
                return False
        if write.method == "start_session":
            key = str(kwargs.pop("key"))
            kwargs["write_id"] = key
            session_id = self.store.start_session(*args, **kwargs)
            self.writer.bind(key, session_id)
            return session_id
        if write.method == "end_session" and args:
            args[0] = self._session_id(args[0], required=True)
        elif write.method == "record_activity":
            if "session_id" in kwargs:
                kwargs["session_id"] = self._session_id(kwargs["session_id"])
            elif len(args) > _RECORD_ACTIVITY_SESSION:
                args[_RECORD_ACTIVITY_SESSION] = self._session_id(args[_RECORD_ACTIVITY_SESSION])
        return getattr(self.store, write.method)(*args, **kwargs)

    def _session_id(self, key: Any, required: bool = False) -> int | None:
        if not isinstance(key, str):
            return key if isinstance(key, int) else None
        session_id = self.writer.binds.get(key)
        if session_id is None:
            if required:
                raise StoreRefused(f"session_id: the session {key} was never stored")
            log.warning("session %s was never stored; the run is logged without it", key)
        return session_id

    def _done(self, write: Write, result: Any) -> None:
        if isinstance(result, Profile):
            with self._cache_lock:
                self._cache[result.user_id] = result
