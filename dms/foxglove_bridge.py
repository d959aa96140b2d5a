"""``dms foxglove``: a robot's keys, live, in Foxglove (through foxglove-sdk).

A Zenoh client of the daemons (:class:`dms.bus.ZenohClient`) forwards each sample on
``robots/<id>/**`` to a Foxglove channel named after its key (``/robots/mini/dms/state``),
served by foxglove-sdk's WebSocket server. Channels of the contract's messages carry
their JSON Schema, so Foxglove's panels know the fields: a Plot of
``/robots/mini/dms/state.motivation.drives.rest`` draws a drive, a Raw Messages or
Log panel shows ``dms/decision`` with its ``why``. The daemon's outputs
(:data:`OUTPUT_KEYS`) are advertised at start for the robot named (with ``--robot '*'``,
for each robot when it first speaks), so a panel can subscribe before the first
decision; other channels are made when a key first speaks, at most :data:`MAX_CHANNELS`
at once (the one seen longest ago is closed); samples that are not JSON objects, or
larger than :data:`MAX_MESSAGE_BYTES`, are counted and dropped.

What the daemon keeps to itself unless ``[privacy]`` says otherwise stays out of
Foxglove too, unless the bridge is told (``personal_data``): what people said or chose
(:data:`HELD_BACK_KEYS` are not forwarded) and, in every other message, user ids and free
text (:data:`PERSONAL_FIELDS`, replaced by :data:`HIDDEN`).

foxglove-sdk speaks the WebSocket subprotocol ``foxglove.sdk.v1`` only; older clients (ROS
tools, Lichtblick, PlotJuggler) offer ``foxglove.websocket.v1``, the same protocol under
its former name. :class:`OriginGuard` renames it on the way in and back on the way out,
so both connect (:func:`negotiate`).

A web page the robot's user opens could connect to the bridge too (browsers let any
page open a WebSocket to localhost), and foxglove-sdk's server does not look at the
``Origin`` header. So the SDK serves on an ephemeral loopback port over TLS with a
certificate made at start (a browser refuses it; only this process trusts it), and
:class:`OriginGuard` serves the port people connect to: it refuses a handshake from a
foreign origin and passes the others through.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import ssl
import threading
import time
from collections import OrderedDict
from collections.abc import Iterable
from typing import Any

from dms.kernel import keys
from dms.kernel.messages import SCHEMAS, json_schema

log = logging.getLogger(__name__)

PARAMS_PREFIX = "params/"

HELD_BACK_KEYS = frozenset({keys.PERCEPTION_SPEECH, keys.PERCEPTION_SCREEN})
"""Keys whose every message is personal: what the user said, what they tapped."""
PERSONAL_FIELDS = frozenset({"user_id", "text", "choice", "choices", "detail", "evidence"})
"""Fields that carry a user id or free text (what the robot says, a decision's detail
quoting the user), at any depth; a ``user`` object's ``id`` too."""
HIDDEN = "(hidden)"

OUTPUT_KEYS = (
    keys.DMS_STATE,
    keys.DMS_DECISION,
    keys.DMS_ERRORS,
    keys.DMS_BEHAVIOR,
    keys.ROBOT_COMMAND,
)
"""What the daemon publishes: advertised before any of it is said."""

MAX_CHANNELS = 256
"""Channels open at once; a key seen after them closes the one seen longest ago (a peer
that makes up keys cannot make the bridge grow)."""
MAX_MESSAGE_BYTES = 256 * 1024
"""Larger samples are dropped unread: the daemon's messages are a few kilobytes."""

HANDSHAKE_TIMEOUT_S = 10.0
"""A client that has not sent its whole WebSocket handshake by then is dropped."""
_LOOPBACK_HOSTS = ("127.0.0.1", "localhost", "[::1]")


def schema_for(relative_key: str) -> dict[str, Any] | None:
    """The JSON Schema of a key's messages (``dms/state`` -> DmsState), None if unknown."""
    name = "params" if relative_key.startswith(PARAMS_PREFIX) else relative_key.replace("/", "_")
    model = SCHEMAS.get(name)
    return json_schema(model) if model is not None else None


def redact(value: Any, field: str | None = None) -> Any:
    """``value`` with its :data:`PERSONAL_FIELDS` (and a ``user``'s ``id``) hidden."""
    if isinstance(value, dict):
        out: dict[str, Any] = {}
        for key, item in value.items():
            personal = key in PERSONAL_FIELDS or (field == "user" and key == "id")
            out[key] = _hidden(item) if personal else redact(item, key)
        return out
    if isinstance(value, list):
        return [redact(item, field) for item in value]
    return value


def _hidden(value: Any) -> Any:
    """A stand-in of the same shape, so that the message still fits its schema."""
    if isinstance(value, list):
        return []
    return HIDDEN if isinstance(value, str) else None


def _relative(key: str) -> str:
    """``dms/state`` of ``robots/mini/dms/state``."""
    return key.split("/", 2)[2] if key.count("/") >= 2 else key


class FoxgloveBridge:
    """Samples in, Foxglove channels out; one per process (``dms foxglove``).

    ``allowed_origins``: web origins allowed besides loopback ones (:class:`OriginGuard`);
    ``personal_data``: forward what ``[privacy]`` holds back (the module's docstring);
    ``every_robot``: it bridges every robot, and advertises the outputs of each one when
    it first speaks (otherwise :meth:`advertise` names the robot).
    """

    def __init__(
        self,
        host: str = "127.0.0.1",
        port: int = 8765,
        allowed_origins: Iterable[str] = (),
        personal_data: bool = False,
        max_channels: int = MAX_CHANNELS,
        max_message_bytes: int = MAX_MESSAGE_BYTES,
        every_robot: bool = False,
    ) -> None:
        import foxglove  # the SDK's native module loads only for this command

        from dms.secure import cert_pem, issue, key_pem, make_ca

        self._foxglove = foxglove
        self.personal_data = personal_data
        ca = make_ca("foxglove")
        leaf = issue(ca, "foxglove", "local", hosts=("localhost",))
        self.server = foxglove.start_server(
            name="dms",
            host="127.0.0.1",
            port=0,
            tls_cert=cert_pem(leaf.cert),
            tls_key=key_pem(leaf.key),
        )
        upstream = ssl.create_default_context(cadata=cert_pem(ca.cert).decode())
        try:
            self.guard = OriginGuard(host, port, int(self.server.port), upstream, allowed_origins)
        except BaseException:
            self.server.stop()
            raise
        self._channels: OrderedDict[str, Any] = OrderedDict()
        """Open channels by key, the one seen longest ago first."""
        self.max_channels = max_channels
        self.max_message_bytes = max_message_bytes
        self._lock = threading.Lock()
        self.every_robot = every_robot
        self._robots: set[str] = set()
        """Robots whose outputs are advertised (at most ``max_channels``)."""
        self.forwarded = 0
        self.dropped = 0
        self.held_back = 0
        self.too_big = 0
        self.closed = 0
        """Channels closed to keep at most ``max_channels``."""

    @property
    def port(self) -> int:
        """The port Foxglove connects to (the guard's)."""
        return self.guard.port

    def advertise(self, robot_id: str) -> None:
        """Open the channels of ``robot_id``'s outputs (:data:`OUTPUT_KEYS`) now, before
        they speak: Foxglove lists them at once, and a decision's channel is there to
        subscribe to before the first decision."""
        with self._lock:
            if robot_id in self._robots or len(self._robots) >= self.max_channels:
                return
            self._robots.add(robot_id)
        for output in OUTPUT_KEYS:
            self._channel(keys.absolute(robot_id, output))

    def on_sample(self, key: str, payload: bytes) -> None:
        """Forward one Zenoh sample (``robots/<id>/<key>``); called from Zenoh's threads."""
        parts = key.split("/", 2)
        if self.every_robot and len(parts) == 3 and parts[0] == "robots":
            self.advertise(parts[1])
        relative = _relative(key)
        if not self.personal_data and relative in HELD_BACK_KEYS:
            self.held_back += 1
            return
        if len(payload) > self.max_message_bytes:
            self.too_big += 1
            return
        try:
            message = json.loads(payload)
        except (ValueError, RecursionError):
            message = None
        if not isinstance(message, dict):
            self.dropped += 1
            return
        if not self.personal_data:
            try:
                message = redact(message)
            except RecursionError:
                self.dropped += 1
                return
        channel = self._channel(key)
        channel.log(message, log_time=time.time_ns())
        self.forwarded += 1

    def _channel(self, key: str) -> Any:
        """The channel of ``key``, made when the key first speaks (or again after it was
        closed); past ``max_channels`` the one seen longest ago is closed."""
        with self._lock:
            channel = self._channels.get(key)
            if channel is not None:
                self._channels.move_to_end(key)
                return channel
            schema = schema_for(_relative(key))
            channel = self._foxglove.Channel("/" + key, schema=schema, message_encoding="json")
            self._channels[key] = channel
            while len(self._channels) > self.max_channels:
                _, oldest = self._channels.popitem(last=False)
                oldest.close()
                self.closed += 1
            return channel

    def channels(self) -> list[str]:
        """The keys of the open channels, the one seen longest ago first."""
        with self._lock:
            return list(self._channels)

    def stop(self) -> None:
        try:
            self.guard.stop()
        finally:
            self.server.stop()


def loopback_origins(port: int) -> set[str]:
    """The origins of pages served on this machine's loopback at ``port``."""
    return {f"{scheme}://{host}:{port}" for scheme in ("http", "https") for host in _LOOPBACK_HOSTS}


SDK_SUBPROTOCOL = "foxglove.sdk.v1"
"""The subprotocol foxglove-sdk's server accepts."""
LEGACY_SUBPROTOCOL = "foxglove.websocket.v1"
"""The same protocol under its former name, which older clients offer."""


def _subprotocols(head: bytes) -> list[str]:
    """The subprotocols a handshake offers, in its order."""
    offered: list[str] = []
    for line in head.split(b"\r\n")[1:]:
        name, _, value = line.partition(b":")
        if name.strip().lower() == b"sec-websocket-protocol":
            offered += [p.strip() for p in value.decode("latin-1").split(",") if p.strip()]
    return offered


def negotiate(head: bytes) -> tuple[bytes, bool]:
    """The handshake to send the SDK's server, and whether its answer must be renamed
    back: a client offering ``foxglove.websocket.v1`` but not ``foxglove.sdk.v1`` is
    offered to the server under the new name (the protocol is the same)."""
    offered = _subprotocols(head)
    if SDK_SUBPROTOCOL in offered or LEGACY_SUBPROTOCOL not in offered:
        return head, False
    lines = head.split(b"\r\n")
    for index, line in enumerate(lines):
        name, _, _ = line.partition(b":")
        if index and name.strip().lower() == b"sec-websocket-protocol":
            lines[index] = b"Sec-WebSocket-Protocol: " + SDK_SUBPROTOCOL.encode()
    return b"\r\n".join(lines), True


def rename_back(head: bytes) -> bytes:
    """The SDK's handshake answer with ``foxglove.sdk.v1`` named as the client asked."""
    return head.replace(
        b"Sec-WebSocket-Protocol: " + SDK_SUBPROTOCOL.encode(),
        b"Sec-WebSocket-Protocol: " + LEGACY_SUBPROTOCOL.encode(),
    ).replace(
        b"sec-websocket-protocol: " + SDK_SUBPROTOCOL.encode(),
        b"sec-websocket-protocol: " + LEGACY_SUBPROTOCOL.encode(),
    )


def _origins(head: bytes) -> list[str]:
    """The ``Origin`` header values of an HTTP request head (lower case)."""
    found = []
    for line in head.split(b"\r\n")[1:]:
        name, _, value = line.partition(b":")
        if name.strip().lower() == b"origin":
            found.append(value.strip().decode("latin-1").lower().rstrip("/"))
    return found


class OriginGuard:
    """A TCP front of the SDK's server that checks each WebSocket handshake's ``Origin``.

    A client without an ``Origin`` header (a native client: the Foxglove desktop app,
    a script) passes, and so does one from a loopback page of this port or an origin in
    ``allowed``; any other gets ``403 Forbidden``. Once a handshake passes, bytes are
    copied both ways to the SDK's server (over TLS, trusted through ``upstream``).
    Listens as soon as it is made (a port in use raises ``OSError`` here); serves on its
    own thread until :meth:`stop`.
    """

    def __init__(
        self,
        host: str,
        port: int,
        upstream_port: int,
        upstream: ssl.SSLContext,
        allowed: Iterable[str] = (),
    ) -> None:
        self._upstream_port = upstream_port
        self._upstream = upstream
        self._loop = asyncio.new_event_loop()
        try:
            self._server = self._loop.run_until_complete(
                asyncio.start_server(self._serve, host, port)
            )
        except BaseException:
            self._loop.close()
            raise
        self.port = int(self._server.sockets[0].getsockname()[1])
        self.allowed = loopback_origins(self.port) | {
            origin.lower().rstrip("/") for origin in allowed
        }
        self.refused = 0
        self._thread = threading.Thread(
            target=self._loop.run_forever, name="dms-foxglove-guard", daemon=True
        )
        self._thread.start()

    def admits(self, origins: list[str]) -> bool:
        """No ``Origin`` (a native client), or exactly one that is allowed."""
        return not origins or (len(origins) == 1 and origins[0] in self.allowed)

    async def _serve(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        try:
            head = await asyncio.wait_for(reader.readuntil(b"\r\n\r\n"), HANDSHAKE_TIMEOUT_S)
        except (asyncio.IncompleteReadError, asyncio.LimitOverrunError, TimeoutError, OSError):
            writer.close()
            return
        origins = _origins(head)
        if not self.admits(origins):
            self.refused += 1
            shown = ", ".join(origins)
            log.warning("refused a WebSocket from origin %s (--allow-origin allows one)", shown)
            body = b"foreign origin: refused (dms foxglove --allow-origin allows one)\n"
            writer.write(
                b"HTTP/1.1 403 Forbidden\r\nContent-Type: text/plain\r\n"
                + f"Content-Length: {len(body)}\r\nConnection: close\r\n\r\n".encode()
                + body
            )
            await _close(writer)
            return
        try:
            up_reader, up_writer = await asyncio.open_connection(
                "127.0.0.1", self._upstream_port, ssl=self._upstream, server_hostname="localhost"
            )
        except (OSError, ssl.SSLError) as error:
            log.warning("foxglove server unreachable: %s", error)
            await _close(writer)
            return
        head, legacy = negotiate(head)
        up_writer.write(head)
        if legacy:
            try:
                answer = await asyncio.wait_for(
                    up_reader.readuntil(b"\r\n\r\n"), HANDSHAKE_TIMEOUT_S
                )
            except (asyncio.IncompleteReadError, asyncio.LimitOverrunError, TimeoutError, OSError):
                await _close(up_writer)
                await _close(writer)
                return
            writer.write(rename_back(answer))
        await asyncio.gather(_pipe(reader, up_writer), _pipe(up_reader, writer))

    def stop(self) -> None:
        """Stop listening, drop the connections, end the thread."""

        async def shut() -> None:
            self._server.close()
            current = asyncio.current_task()
            for task in asyncio.all_tasks():
                if task is not current:
                    task.cancel()

        if self._loop.is_closed():
            return
        asyncio.run_coroutine_threadsafe(shut(), self._loop).result(5)
        self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join(5)
        if not self._thread.is_alive():
            self._loop.close()


async def _pipe(source: asyncio.StreamReader, sink: asyncio.StreamWriter) -> None:
    """Copy until ``source`` ends or either side fails; then close ``sink``."""
    try:
        while data := await source.read(65536):
            sink.write(data)
            await sink.drain()
    except (OSError, ssl.SSLError):
        pass
    finally:
        await _close(sink)


async def _close(writer: asyncio.StreamWriter) -> None:
    writer.close()
    with contextlib.suppress(OSError, ssl.SSLError):
        await writer.wait_closed()
