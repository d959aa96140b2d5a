"""The Zenoh adapter: the only module that imports zenoh.

:class:`ZenohBus` is the daemon's side: it subscribes to the robot's input keys and
liveliness tokens, publishes JSON on output keys, serves the queryables and declares
``alive/dms``. :class:`ZenohClient` is the other side, used by the simulated robot and
visitor, the recorder and anyone scripting the daemon from Python.

Sessions are opened as peers with multicast scouting off; endpoints come from flags or
from a Zenoh JSON5 file (which is also how a deployment turns on TLS and access control).
"""

from __future__ import annotations

import json
import logging
import re
import threading
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import zenoh

from dms.kernel import keys
from dms.kernel.errors import ConfigError
from dms.rate_caps import DropTally

log = logging.getLogger(__name__)

DEFAULT_LISTEN = ("tcp/127.0.0.1:7447",)
DEFAULT_CONNECT = "tcp/127.0.0.1:7447"
"""Where a tool (``dms view``, ``dms echo``...) looks for the daemon by default."""
TOOL_CONNECT_TIMEOUT_S = 5.0
"""How long a tool waits for its endpoints before it says they are unreachable."""
ALIVE_QUERY_TIMEOUT_S = 3.0
"""How long a starting daemon waits for another one's ``alive/dms`` token to answer."""
JSON = zenoh.Encoding.APPLICATION_JSON

InputHandler = Callable[[str, bytes], None]
"""Called with (key relative to the robot, raw payload) from a Zenoh thread."""
LivelinessHandler = Callable[[str, bool], None]
"""Called with (input key, alive) when a module's ``alive/<key>`` token comes or goes."""
QueryHandler = Callable[[str, bytes | None], tuple[bool, Any]]
"""Called with (relative key, payload); returns (ok, JSON-able reply)."""
TOKEN_INPUTS = frozenset(keys.INPUT_KEYS)
"""The ``alive/<key>`` tokens the daemon acts on: one per input. A token on any other key
(but ``alive/dms``) is counted in :attr:`ZenohBus.ignored_tokens` and goes no further, so
a peer declaring thousands of distinct tokens costs a counter, never the daemon's memory.
The inputs' own tokens are not rate-capped: a dropped withdrawal would leave a module that
went away counted as present."""
IGNORED_TOKENS = "alive/**"
"""The key :attr:`ZenohBus.ignored_tokens` counts under, and its reports name."""


def one_line(error: BaseException) -> str:
    """Zenoh's (often multi-line) error as one line, without its Rust source location."""
    text = " ".join(str(error).split())
    return re.sub(r" at /\S+\.rs:\d+\.?", "", text) or type(error).__name__


_ENDPOINT = re.compile(r"[a-z][a-z0-9-]*/[^\s?#]+(\?[^#\s]*)?(#\S*)?")
_IP_PROTOCOLS = frozenset({"tcp", "udp", "tls", "quic", "ws"})


def check_endpoint(endpoint: str) -> str:
    """``endpoint`` when it is a Zenoh locator (``tcp/HOST:PORT``, ``tls/...``), else one
    line a person can act on (Zenoh's own says it through a Rust debug dump)."""
    text = endpoint.strip()
    ok = _ENDPOINT.fullmatch(text) is not None
    protocol, _, address = text.partition("/")
    if ok and protocol in _IP_PROTOCOLS:
        port = address.split("?", 1)[0].split("#", 1)[0].rpartition(":")[2]
        ok = port.isdigit() and int(port) <= 65535
    if not ok:
        raise ConfigError(f"`{endpoint}`: an endpoint is `tcp/HOST:PORT`")
    return text


def make_config(
    listen: Sequence[str] = (),
    connect: Sequence[str] = (),
    config_file: Path | None = None,
) -> zenoh.Config:
    """A peer configuration: endpoints from flags (or the file), multicast scouting off."""
    if config_file is not None:
        try:
            config = zenoh.Config.from_file(str(config_file))
        except (zenoh.ZError, OSError, ValueError) as error:
            raise ConfigError(f"--zenoh-config {config_file}: {one_line(error)}") from None
    else:
        config = zenoh.Config()
        config.insert_json5("mode", json.dumps("peer"))
    listen = [check_endpoint(endpoint) for endpoint in listen]
    connect = [check_endpoint(endpoint) for endpoint in connect]
    try:
        if listen:
            config.insert_json5("listen/endpoints", json.dumps(list(listen)))
        if connect:
            config.insert_json5("connect/endpoints", json.dumps(list(connect)))
        config.insert_json5("scouting/multicast/enabled", "false")
    except (zenoh.ZError, ValueError) as error:
        raise ConfigError(f"zenoh endpoints: {error}") from None
    return config


def make_router_config(listen: Sequence[str] = (), config_file: Path | None = None) -> zenoh.Config:
    """``dms router``'s configuration: the same endpoints and file, in router mode."""
    config = make_config(listen, (), config_file)
    config.insert_json5("mode", json.dumps("router"))
    return config


class ZenohRouter:
    """Zenoh's own router, run in this process (``dms router``): the daemons of a fleet
    connect to it, and it routes their keys and liveliness tokens to each other and to
    the tools (``dms fleet status``, ``dms view``). Nothing of dms runs in it."""

    def __init__(self, config: zenoh.Config) -> None:
        self.session = open_session(config)

    @property
    def zid(self) -> str:
        return str(self.session.info.zid())

    def close(self) -> None:
        self.session.close()


def make_client_config(
    connect: Sequence[str] = (),
    config_file: Path | None = None,
    timeout_s: float = TOOL_CONNECT_TIMEOUT_S,
) -> zenoh.Config:
    """A tool's configuration: it listens nowhere and connects to ``connect`` (by default
    the daemon's default endpoint), or to the file's endpoints. Given one endpoint (a
    router, or a daemon) it is a Zenoh client of it: routed at once, so a query made
    right after opening is answered (a peer behind a router first waits for its links to
    the other peers). Given several (daemons without a router) it is a peer of each.
    Opening fails, with Zenoh's reason, when none answers within ``timeout_s``; once
    open, a lost link is retried in the background (a restarted daemon is found again)."""
    if config_file is None and not connect:
        connect = (DEFAULT_CONNECT,)
    config = make_config(connect=connect, config_file=config_file)
    try:
        if config_file is None:
            config.insert_json5("listen/endpoints", "[]")
            if len(connect) == 1:
                config.insert_json5("mode", json.dumps("client"))
        config.insert_json5("connect/exit_on_failure", "true")
        config.insert_json5("connect/timeout_ms", str(int(timeout_s * 1000)))
    except (zenoh.ZError, ValueError) as error:
        raise ConfigError(f"zenoh endpoints: {error}") from None
    return config


def open_session(config: zenoh.Config) -> zenoh.Session:
    """Open a session or raise ConfigError with Zenoh's reason (port in use, bad endpoint)."""
    try:
        return zenoh.open(config)
    except zenoh.ZError as error:
        raise ConfigError(f"cannot open the Zenoh session: {one_line(error)}") from None


def check_key_expr(text: str) -> str:
    """``text`` when it is a valid Zenoh key expression (wildcards allowed), else ConfigError."""
    try:
        return str(zenoh.KeyExpr.autocanonize(text))
    except (zenoh.ZError, ValueError, TypeError) as error:
        raise ConfigError(f"bad key expression {text!r}: {one_line(error)}") from None


def encode(payload: Mapping[str, Any] | Sequence[Any]) -> bytes:
    return json.dumps(payload, separators=(",", ":"), allow_nan=False).encode()


class ZenohBus:
    """The daemon's Zenoh side, for one robot id."""

    def __init__(self, robot_id: str, config: zenoh.Config) -> None:
        self.robot_id = robot_id
        self._config = config
        self._session: zenoh.Session | None = None
        self._entities: list[Any] = []
        self._publishers: dict[str, zenoh.Publisher] = {}
        self._token: zenoh.LivelinessToken | None = None
        self._lock = threading.Lock()
        self.ignored_tokens = DropTally()
        """Tokens declared on keys that are no input, reported once a second with a count."""

    def _key(self, key: str) -> str:
        return keys.absolute(self.robot_id, key)

    def start(self, queries: Mapping[str, QueryHandler]) -> None:
        """Open the session, serve ``queries`` and declare the publishers; no input is
        heard until :meth:`listen`.

        ``queries`` maps a relative key (``dms/state``) or prefix ending in ``/``
        (``users/``) to its handler.
        """
        session = self._session = open_session(self._config)
        self.refuse_if_alive()
        for key, handler in queries.items():
            expr = self._key(key + "**") if key.endswith("/") else self._key(key)
            self._entities.append(session.declare_queryable(expr, self._serve(handler)))
        for key in (
            keys.DMS_STATE,
            keys.DMS_DECISION,
            keys.DMS_ERRORS,
            keys.ROBOT_COMMAND,
            keys.ROBOT_JOINTS,
        ):
            # The state and the joints come again next tick, so a congested link may drop
            # one; a decision, a rejection or a robot command is said once, so it waits for
            # room instead (Zenoh closes a link blocked for longer than its block timeout).
            congestion = (
                zenoh.CongestionControl.DROP
                if key in (keys.DMS_STATE, keys.ROBOT_JOINTS)
                else zenoh.CongestionControl.BLOCK
            )
            self._publishers[key] = session.declare_publisher(
                self._key(key), encoding=JSON, express=True, congestion_control=congestion
            )

    def listen(self, on_input: InputHandler, on_liveliness: LivelinessHandler) -> None:
        """Subscribe to every input and to the input modules' ``alive/`` tokens."""
        session = self._session
        assert session is not None, "start() first"
        robot = self.robot_id

        def on_sample(sample: zenoh.Sample) -> None:
            key = keys.relative(robot, str(sample.key_expr))
            if key is not None and sample.kind == zenoh.SampleKind.PUT:
                on_input(key, sample.payload.to_bytes())

        for key in keys.INPUT_KEYS:
            # Only other processes' messages are inputs: the joints the daemon publishes for
            # its in-process robot are not heard back as if a robot had sent them.
            self._entities.append(
                session.declare_subscriber(
                    self._key(key), on_sample, allowed_origin=zenoh.Locality.REMOTE
                )
            )

        alive_prefix = self._key(keys.ALIVE_PREFIX)

        def on_token(sample: zenoh.Sample) -> None:
            name = str(sample.key_expr)
            if not name.startswith(alive_prefix):
                return
            key, alive = name[len(alive_prefix) :], sample.kind == zenoh.SampleKind.PUT
            if key in TOKEN_INPUTS:
                on_liveliness(key, alive)
            elif alive and key != "dms":
                self.ignored_tokens.add(IGNORED_TOKENS, latest=keys.ALIVE_PREFIX + key)

        self._entities.append(
            session.liveliness().declare_subscriber(self._key("alive/**"), on_token, history=True)
        )

    def refuse_if_alive(self, timeout_s: float = ALIVE_QUERY_TIMEOUT_S) -> None:
        """Raise ConfigError when another daemon already declares this robot's ``alive/dms``.

        Asked before anything is declared: the refused daemon has served no query and
        subscribed to nothing, and its session is closed here, so that nothing it would
        publish while stopping (a shutdown state) reaches the live robot's keys.
        """
        assert self._session is not None
        key = self._key(keys.ALIVE_DMS)
        try:
            replies = self._session.liveliness().get(key, timeout=timeout_s)
            alive = any(reply.ok is not None for reply in replies)
        except zenoh.ZError as error:
            self._abandon()
            raise ConfigError(f"cannot ask whether {key} is alive: {one_line(error)}") from None
        if alive:
            self._abandon()
            raise ConfigError(
                f"robot {self.robot_id} is already running: {key} is declared on the bus"
                " (stop that daemon, or give this one another --robot-id)"
            )

    def _abandon(self) -> None:
        """Close the session of a daemon that will not start (publishing becomes a no-op)."""
        if self._session is not None:
            self._session.close()
            self._session = None

    def _serve(self, handler: QueryHandler) -> Callable[[zenoh.Query], None]:
        robot = self.robot_id

        def on_query(query: zenoh.Query) -> None:
            # A query stays open until its object is dropped: an error on the way (kept
            # alive by a traceback's frames) held the asker for its whole timeout. So
            # every query is answered once and closed here, whatever happened.
            try:
                key = keys.relative(robot, str(query.key_expr)) or ""
                payload = query.payload.to_bytes() if query.payload is not None else None
                try:
                    ok, reply = handler(key, payload)
                except Exception as error:  # a bug: the asker gets one line, the log the rest
                    log.exception("the query on %s failed", query.key_expr)
                    ok, reply = False, {"error": f"internal error: {one_line(error)}"}
                if ok:
                    query.reply(query.key_expr, encode(reply), encoding=JSON)
                else:
                    query.reply_err(encode(reply), encoding=JSON)
            finally:
                query.drop()

        return on_query

    def publish(self, key: str, payload: Mapping[str, Any]) -> None:
        """Publish JSON on ``robots/<id>/<key>`` (thread-safe)."""
        data = encode(payload)
        publisher = self._publishers.get(key)
        if publisher is not None:
            publisher.put(data)
        elif self._session is not None:
            self._session.put(self._key(key), data, encoding=JSON)

    def declare_alive(self) -> None:
        """Declare ``alive/dms``: the daemon is ready."""
        assert self._session is not None
        self._token = self._session.liveliness().declare_token(self._key(keys.ALIVE_DMS))

    def stop_listening(self) -> None:
        """Withdraw ``alive/dms`` and stop hearing inputs and queries, keeping the
        publishers: the first step of a stop, so that a flood still coming costs the
        stopping daemon nothing while it publishes its last state."""
        with self._lock:
            if self._token is not None:
                self._token.undeclare()
                self._token = None
            for entity in self._entities:
                entity.undeclare()
            self._entities.clear()

    def close(self) -> None:
        self.stop_listening()
        with self._lock:
            for publisher in self._publishers.values():
                publisher.undeclare()
            self._entities.clear()
            self._publishers.clear()
            if self._session is not None:
                self._session.close()
                self._session = None


class ZenohClient:
    """Another process's side of the key space: publish inputs, watch outputs, query.

    Used by the simulated robot (``dms sim robot``), the demo visitor and the recorder.
    """

    def __init__(self, robot_id: str, config: zenoh.Config) -> None:
        self.robot_id = robot_id
        self.session = open_session(config)
        self._entities: list[Any] = []

    def __enter__(self) -> ZenohClient:
        return self

    def __exit__(self, *_exc: object) -> None:
        self.close()

    def key(self, key: str) -> str:
        return keys.absolute(self.robot_id, key)

    def publish(self, key: str, payload: Mapping[str, Any]) -> None:
        self.session.put(self.key(key), encode(payload), encoding=JSON)

    def subscribe(self, key: str, handler: Callable[[str, Any], None]) -> None:
        """Call ``handler(relative key, decoded JSON)`` for each sample on ``key``."""
        robot = self.robot_id

        def on_sample(sample: zenoh.Sample) -> None:
            rel = keys.relative(robot, str(sample.key_expr)) or str(sample.key_expr)
            try:
                payload = json.loads(sample.payload.to_bytes())
            except ValueError:
                return  # not ours to judge: the daemon never publishes invalid JSON
            handler(rel, payload)

        self._entities.append(self.session.declare_subscriber(self.key(key), on_sample))

    def subscribe_raw(self, key_expr: str, handler: Callable[[str, bytes], None]) -> None:
        """Call ``handler(full key, raw bytes)`` for each sample on an absolute key expression."""

        def on_sample(sample: zenoh.Sample) -> None:
            handler(str(sample.key_expr), sample.payload.to_bytes())

        self._entities.append(self.session.declare_subscriber(key_expr, on_sample))

    def declare_token(self, key: str) -> zenoh.LivelinessToken:
        token = self.session.liveliness().declare_token(self.key(key))
        self._entities.append(token)
        return token

    def wait_alive(self, key: str, timeout_s: float) -> bool:
        """Wait until the token ``robots/<id>/<key>`` exists."""
        seen = threading.Event()

        def on_token(sample: zenoh.Sample) -> None:
            if sample.kind == zenoh.SampleKind.PUT:
                seen.set()

        sub = self.session.liveliness().declare_subscriber(self.key(key), on_token, history=True)
        try:
            return seen.wait(timeout_s)
        finally:
            sub.undeclare()

    def query(
        self, key: str, payload: Mapping[str, Any] | None = None, timeout_s: float = 5.0
    ) -> list[tuple[bool, Any]]:
        """``session.get`` on ``robots/<id>/<key>``: (ok, decoded JSON) per reply."""
        return self.query_absolute(self.key(key), payload, timeout_s)

    def query_absolute(
        self, key_expr: str, payload: Mapping[str, Any] | None = None, timeout_s: float = 5.0
    ) -> list[tuple[bool, Any]]:
        """``session.get`` on any key expression (another robot's, for fleet tools)."""
        replies = self.session.get(
            key_expr,
            payload=encode(payload) if payload is not None else None,
            timeout=timeout_s,
        )
        out: list[tuple[bool, Any]] = []
        for reply in replies:
            if reply.ok is not None:
                out.append((True, json.loads(reply.ok.payload.to_bytes())))
            elif reply.err is not None:
                out.append((False, json.loads(reply.err.payload.to_bytes())))
        return out

    def alive_robots(self, timeout_s: float = 2.0) -> list[str]:
        """The robot ids whose daemon's ``alive/dms`` token exists now, sorted."""
        pattern = keys.absolute("*", keys.ALIVE_DMS)
        found: set[str] = set()
        for reply in self.session.liveliness().get(pattern, timeout=timeout_s):
            if reply.ok is not None:
                parts = str(reply.ok.key_expr).split("/")
                if len(parts) > 1:
                    found.add(parts[1])
        return sorted(found)

    def watch_tokens(self, key_expr: str, handler: Callable[[str, bool], None]) -> None:
        """Call ``handler(full key, alive)`` for each liveliness token on an absolute key
        expression: first for the tokens that exist now, then as they come and go."""

        def on_token(sample: zenoh.Sample) -> None:
            handler(str(sample.key_expr), sample.kind == zenoh.SampleKind.PUT)

        self._entities.append(
            self.session.liveliness().declare_subscriber(key_expr, on_token, history=True)
        )

    def tokens(self, key_expr: str, timeout_s: float = 2.0) -> list[str]:
        """The liveliness tokens that exist now on an absolute key expression, sorted."""
        found = {
            str(reply.ok.key_expr)
            for reply in self.session.liveliness().get(key_expr, timeout=timeout_s)
            if reply.ok is not None
        }
        return sorted(found)

    def close(self) -> None:
        for entity in self._entities:
            entity.undeclare()
        self._entities.clear()
        self.session.close()
