"""``dms foxglove``: a robot's keys, live, in Foxglove (through foxglove-sdk).

A Zenoh client of the daemons (:class:`dms.bus.ZenohClient`) forwards each sample on
``robots/<id>/**`` to a Foxglove channel named after its key (``/robots/mini/dms/state``),
served by foxglove-sdk's WebSocket server. Channels of the contract's messages carry
their JSON Schema, so Foxglove's panels know the fields: a Plot of
``/robots/mini/dms/state.motivation.drives.rest`` draws a drive, a Raw Messages or
Log panel shows ``dms/decision`` with its ``why``. Channels are made when a key first
speaks; samples that are not JSON objects are counted and dropped.
"""

from __future__ import annotations

import json
import logging
import threading
import time
from typing import Any

from dms.kernel.messages import SCHEMAS, json_schema

log = logging.getLogger(__name__)

PARAMS_PREFIX = "params/"


def schema_for(relative_key: str) -> dict[str, Any] | None:
    """The JSON Schema of a key's messages (``dms/state`` -> DmsState), None if unknown."""
    name = "params" if relative_key.startswith(PARAMS_PREFIX) else relative_key.replace("/", "_")
    model = SCHEMAS.get(name)
    return json_schema(model) if model is not None else None


class FoxgloveBridge:
    """Samples in, Foxglove channels out; one per process (``dms foxglove``)."""

    def __init__(self, host: str = "127.0.0.1", port: int = 8765) -> None:
        import foxglove  # the SDK's native module loads only for this command

        self._foxglove = foxglove
        self.server = foxglove.start_server(name="dms", host=host, port=port)
        self._channels: dict[str, Any] = {}
        self._lock = threading.Lock()
        self.forwarded = 0
        self.dropped = 0

    @property
    def port(self) -> int:
        return int(self.server.port)

    def on_sample(self, key: str, payload: bytes) -> None:
        """Forward one Zenoh sample (``robots/<id>/<key>``); called from Zenoh's threads."""
        try:
            message = json.loads(payload)
        except ValueError:
            message = None
        if not isinstance(message, dict):
            self.dropped += 1
            return
        channel = self._channel(key)
        channel.log(message, log_time=time.time_ns())
        self.forwarded += 1

    def _channel(self, key: str) -> Any:
        with self._lock:
            channel = self._channels.get(key)
            if channel is None:
                relative = key.split("/", 2)[2] if key.count("/") >= 2 else key
                schema = schema_for(relative)
                channel = self._foxglove.Channel("/" + key, schema=schema, message_encoding="json")
                self._channels[key] = channel
            return channel

    def stop(self) -> None:
        self.server.stop()
