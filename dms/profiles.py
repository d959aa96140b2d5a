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
from collections.abc import Callable
from datetime import datetime
from pathlib import Path
from typing import Any

from dms.storage import QUEUE_SIZE, RETRY_EVERY_S, StorageWriter, Waiter, Write, sqlite_file
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

_FIND = "find"
"""The read behind :meth:`ProfileService.stored` (the store's ``get`` without the error)."""

_RECORD_ACTIVITY_SESSION = 7  # the position of session_id in ProfileStore.record_activity

ONCE = frozenset(
    {
        "update",
        "record_activity",
        "record_feedback",
        "record_answer",
        "record_interaction",
        "record_initiative",
    }
)
"""Store writes that take a ``write_id`` (``start_session`` takes its key as one)."""


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
        waiter = Waiter()
        self.writer.submit(Write("get_or_create", (user_id, now)), waiter)
        waiter.wait(wait_s)
        if isinstance(waiter.result, Profile):
            return waiter.result
        return self.cached(user_id)

    def ask(self, method: str, *args: Any, wait_s: float = LOAD_WAIT_S) -> Any:
        """A store read, in order behind the writes queued before it, waiting at most
        ``wait_s``: its result, or None when it has not landed by then."""
        waiter = Waiter()
        self.writer.submit(Write(method, args), waiter)
        waiter.wait(wait_s)
        return waiter.result

    def stored(self, user_id: str, wait_s: float = LOAD_WAIT_S) -> bool | None:
        """Whether the store has a profile for ``user_id`` (read off the tick, in order
        behind the writes queued before it); None when the read has not landed in time."""
        found = self.ask(_FIND, user_id, wait_s=wait_s)
        return found if isinstance(found, bool) else None

    def meet_newcomer(self, user_id: str | None) -> None:
        """``user_id`` is in front of the robot, not stored yet (None: nobody is): the
        agenda takes items for her meanwhile (:meth:`met`)."""
        self.newcomer = user_id

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

    def call(self, method: str, *args: Any, **kwargs: Any) -> Any:
        """Queue the store call ``method``; returns None, or for ``start_session`` its key.

        The key stands for the session's id in later calls (``end_session``,
        ``record_activity``), also after a restart when the calls were spooled.
        """
        if method == "start_session":
            key = f"session-{uuid.uuid4().hex}"
            self.writer.submit(Write(method, args, {**kwargs, "key": key}))
            return key
        if method in ONCE and "write_id" not in kwargs:
            kwargs = {**kwargs, "write_id": uuid.uuid4().hex}
        self.writer.submit(Write(method, args, kwargs))
        return None

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
        if write.method == _FIND:
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
