"""An in-memory bus with the daemon-side interface of :class:`dms.bus.ZenohBus`.

For unit tests of the daemon's wiring without sockets: ``inject`` plays another
process publishing an input, ``published`` records what the daemon published, and
``query`` calls a queryable as ``session.get`` would.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import Any

from dms.bus import InputHandler, LivelinessHandler, QueryHandler
from dms.rate_caps import DropTally


class InMemoryBus:
    """Synchronous, single-process stand-in for Zenoh."""

    def __init__(self, robot_id: str = "mini") -> None:
        self.robot_id = robot_id
        self.published: list[tuple[str, dict[str, Any]]] = []
        self.alive = False
        self._on_input: InputHandler | None = None
        self._on_liveliness: LivelinessHandler | None = None
        self._queries: dict[str, QueryHandler] = {}
        self.ignored_tokens = DropTally()
        """As :attr:`dms.bus.ZenohBus.ignored_tokens` (tests call :meth:`token` directly)."""

    def start(self, queries: Mapping[str, QueryHandler]) -> None:
        self._queries = dict(queries)

    def listen(self, on_input: InputHandler, on_liveliness: LivelinessHandler) -> None:
        self._on_input, self._on_liveliness = on_input, on_liveliness

    def publish(self, key: str, payload: Mapping[str, Any]) -> None:
        # Round-trip through JSON so tests see exactly what would go on the wire.
        self.published.append((key, json.loads(json.dumps(payload, allow_nan=False))))

    def declare_alive(self) -> None:
        self.alive = True

    def stop_listening(self) -> None:
        self.alive = False
        self._on_input = self._on_liveliness = None
        self._queries = {}

    def close(self) -> None:
        self.stop_listening()

    # ---------------------------------------------------------------- test side

    def inject(self, key: str, payload: Mapping[str, Any] | bytes) -> None:
        assert self._on_input is not None, "listen() first"
        raw = payload if isinstance(payload, bytes) else json.dumps(payload).encode()
        self._on_input(key, raw)

    def token(self, key: str, alive: bool) -> None:
        assert self._on_liveliness is not None, "listen() first"
        self._on_liveliness(key, alive)

    def query(self, key: str, payload: Mapping[str, Any] | None = None) -> tuple[bool, Any]:
        for prefix, handler in self._queries.items():
            if key == prefix or (prefix.endswith("/") and key.startswith(prefix)):
                raw = json.dumps(payload).encode() if payload is not None else None
                return handler(key, raw)
        raise KeyError(f"no queryable for {key}")

    def messages(self, key: str) -> list[dict[str, Any]]:
        return [payload for k, payload in self.published if k == key]
