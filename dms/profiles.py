"""The controller's view of the profile store: cached snapshots and retried writes.

The decision loop must keep deciding when the database has a problem: this wrapper
keeps the last snapshot of each profile it loaded, reports a failed load, and the
first write of an outage, in one line through ``report`` (the daemon publishes it on
``dms/errors``), queues the writes that failed and every write behind them, and
replays them in order every few seconds.
"""

from __future__ import annotations

import logging
from collections import deque
from collections.abc import Callable
from datetime import datetime
from typing import Any

from memory import Profile, ProfileError, ProfileStore, StoreUnavailable

log = logging.getLogger(__name__)

RETRY_EVERY_S = 5.0
OUTBOX_SIZE = 10_000
"""Writes kept during an outage; beyond it the oldest is lost (and reported)."""


class ProfileService:
    """Profile loads and writes for the controller, resilient to database outages."""

    def __init__(
        self,
        store: ProfileStore,
        report: Callable[[str, str], None],
        outbox_size: int = OUTBOX_SIZE,
    ) -> None:
        self.store = store
        self._report = report
        self._cache: dict[str, Profile] = {}
        self._outbox: deque[tuple[str, tuple[Any, ...], dict[str, Any]]] = deque(maxlen=outbox_size)
        self._last_retry: datetime | None = None

    def load(self, user_id: str, now: datetime) -> Profile | None:
        """Load or create ``user_id``'s profile; the cached one if the store is down."""
        try:
            profile = self.store.get_or_create(user_id, now)
        except StoreUnavailable as error:
            self._report("memory", f"cannot load profile {user_id}: {error}")
            return self._cache.get(user_id)
        self._cache[user_id] = profile
        return profile

    def cached(self, user_id: str) -> Profile | None:
        return self._cache.get(user_id)

    def call(self, method: str, *args: Any, **kwargs: Any) -> Any:
        """Call a store method; on an outage queue it for retry and return None.

        Queued writes go first: a write is never overtaken by a later one.
        """
        if self._outbox and not self._replay():
            self._queue(method, args, kwargs)
            return None
        try:
            result = getattr(self.store, method)(*args, **kwargs)
        except StoreUnavailable as error:
            self._report("memory", f"{method} failed, will retry: {error}")
            self._queue(method, args, kwargs)
            return None
        except ProfileError as error:
            self._report("memory", f"{method} refused: {error}")
            return None
        if isinstance(result, Profile):
            self._cache[result.user_id] = result
        return result

    def _queue(self, method: str, args: tuple[Any, ...], kwargs: dict[str, Any]) -> None:
        """Keep a write for later; a full outbox loses its oldest write, and says so."""
        if len(self._outbox) == self._outbox.maxlen:
            dropped = self._outbox[0][0]
            self._report("memory", f"outbox full: the oldest queued {dropped} is lost")
        self._outbox.append((method, args, kwargs))

    def retry(self, now: datetime) -> None:
        """Replay queued writes, oldest first, at most every RETRY_EVERY_S."""
        if not self._outbox:
            return
        if self._last_retry and (now - self._last_retry).total_seconds() < RETRY_EVERY_S:
            return
        self._last_retry = now
        self._replay()

    def _replay(self) -> bool:
        """Replay queued writes in order; False if the store is still unavailable."""
        while self._outbox:
            method, args, kwargs = self._outbox[0]
            try:
                result = getattr(self.store, method)(*args, **kwargs)
            except StoreUnavailable:
                return False
            except ProfileError as error:
                log.warning("dropping a queued %s: %s", method, error)
            else:
                if isinstance(result, Profile):
                    self._cache[result.user_id] = result
            self._outbox.popleft()
        return True

    @property
    def pending_writes(self) -> int:
        return len(self._outbox)
