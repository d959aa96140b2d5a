"""From outside: ``dms foxglove`` between a real daemon and a client
that speaks Foxglove's WebSocket protocol (as the Foxglove app does).

The bridge is a process, a Zenoh client of the daemon on 127.0.0.1; the test's client
reads the advertised channels (with JSON Schemas), subscribes to the state and the
decisions, and sees the drives and a decision that a request causes.
"""

from __future__ import annotations

import asyncio
import json
import os
import re
import socket
import struct
import subprocess
import sys
import time
from datetime import datetime
from pathlib import Path
from typing import Any

import pytest
import websockets

from tests.integration.harness import StderrLines, free_port, put, running_daemon

pytestmark = pytest.mark.integration

SUBPROTOCOLS = ["foxglove.sdk.v1", "foxglove.websocket.v1"]


class Bridge:
    """``dms foxglove`` in a subprocess; ready when it prints its WebSocket address."""

    def __init__(self, daemon_port: int, *options: str) -> None:
        self.port = free_port()
        self.proc = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "dms.cli",
                "foxglove",
                "--connect",
                f"tcp/127.0.0.1:{daemon_port}",
                "--port",
                str(self.port),
                *options,
            ],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
            env=dict(os.environ, PYTHONUNBUFFERED="1"),
        )
        self.stderr = StderrLines(self.proc)

    def wait_ready(self) -> None:
        self.stderr.wait_for("ws://")

    def stop(self) -> int:
        self.proc.terminate()
        return self.proc.wait(20)


class FoxgloveClient:
    """The client side of Foxglove's WebSocket protocol, as much as the test needs."""

    def __init__(self, ws: Any) -> None:
        self.ws = ws
        self.channels: dict[str, dict[str, Any]] = {}
        self.seen: dict[str, list[dict[str, Any]]] = {}
        self._topics: dict[int, str] = {}
        """Subscription id (= channel id here) -> topic."""

    async def subscribe(self, topic: str) -> None:
        channel_id = int(self.channels[topic]["id"])
        self._topics[channel_id] = topic
        await self._subscribe(channel_id)

    async def _subscribe(self, channel_id: int) -> None:
        subscription = {"id": channel_id, "channelId": channel_id}
        await self.ws.send(json.dumps({"op": "subscribe", "subscriptions": [subscription]}))

    async def until(self, predicate: Any, timeout: float = 20.0) -> None:
        """Read messages until ``predicate()`` holds."""

        async def loop() -> None:
            while not predicate():
                await self._read()

        try:
            await asyncio.wait_for(loop(), timeout)
        except TimeoutError:
            got = {topic: len(messages) for topic, messages in self.seen.items()}
            raise AssertionError(
                f"not seen within {timeout} s; channels {sorted(self.channels)}, got {got}"
            ) from None

    async def _read(self) -> None:
        message = await self.ws.recv()
        if isinstance(message, bytes):
            if message[0] == 1:  # message data: opcode, subscription id, log time, payload
                subscription, _log_time = struct.unpack_from("<IQ", message, 1)
                topic = self._topics[subscription]
                self.seen.setdefault(topic, []).append(json.loads(message[13:]))
            return
        body = json.loads(message)
        if body.get("op") == "advertise":
            for channel in body["channels"]:
                self.channels[channel["topic"]] = channel
        unknown = re.fullmatch(r"Unknown channel ID: (\d+)", str(body.get("message", "")))
        if body.get("op") == "status" and unknown:
            # foxglove-sdk may take a subscription sent right after an advertisement
            # before it has noted that this client has the channel; it says so, and the
            # client subscribes again.
            await self._subscribe(int(unknown.group(1)))


async def _session(port: int, daemon_session: Any) -> FoxgloveClient:
    async with websockets.connect(f"ws://127.0.0.1:{port}", subprotocols=SUBPROTOCOLS) as ws:
        client = FoxgloveClient(ws)
        state, decision = "/robots/mini/dms/state", "/robots/mini/dms/decision"
        await client.until(lambda: state in client.channels)
        await client.subscribe(state)
        await client.until(lambda: len(client.seen.get(state, [])) >= 2)
        # Every output is advertised at start: the decisions' channel is there to
        # subscribe to before the bridge has forwarded any decision.
        assert decision in client.channels and "/robots/mini/robot/command" in client.channels
        await client.subscribe(decision)
        put(daemon_session, "request", {"action": "start", "activity": "jokes", "by": "app"})
        # Two states the daemon published well after the subscription was sent show that
        # the server has taken it (it handles a client's messages at once).
        sent = time.time() + 0.5
        await client.until(lambda: sum(_time(m) > sent for m in client.seen[state]) >= 2)
        put(daemon_session, "request", {"action": "cancel", "activity": "jokes", "by": "app"})
        await client.until(
            lambda: any(d["action"] == "cancel" for d in client.seen.get(decision, []))
        )
        return client


def _time(message: dict[str, Any]) -> float:
    return datetime.fromisoformat(str(message["time"]).replace("Z", "+00:00")).timestamp()


def test_foxglove_sees_the_drives_and_the_decisions(tmp_path: Path) -> None:
    with running_daemon(tmp_path) as (daemon, session):
        bridge = Bridge(daemon.port)
        try:
            bridge.wait_ready()
            client = asyncio.run(_session(bridge.port, session))
        finally:
            code = bridge.stop()
    channels, seen = client.channels, client.seen
    state = channels["/robots/mini/dms/state"]
    assert state["encoding"] == "json" and state["schemaEncoding"] == "jsonschema"
    assert "motivation" in json.loads(state["schema"])["properties"]
    drives = seen["/robots/mini/dms/state"][-1]["motivation"]["drives"]
    assert set(drives) >= {"rest", "social", "play"}, drives
    decision = channels["/robots/mini/dms/decision"]
    assert json.loads(decision["schema"])["title"] == "Decision"
    assert code == 0, "SIGTERM stops the bridge cleanly"


def _foxglove(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "dms.cli", "foxglove", *args],
        capture_output=True,
        text=True,
        timeout=60,
    )


def test_a_port_in_use_and_an_unreachable_daemon_are_one_line_each() -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        done = _foxglove("--port", str(port), "--connect", f"tcp/127.0.0.1:{free_port()}")
    assert done.returncode == 1
    assert done.stderr.startswith(f"dms: --port {port}:"), done.stderr
    assert len(done.stderr.strip().splitlines()) == 1, done.stderr
    nobody = free_port()
    done = _foxglove("--port", str(free_port()), "--connect", f"tcp/127.0.0.1:{nobody}")
    assert done.returncode == 1
    assert f"tcp/127.0.0.1:{nobody}" in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1, done.stderr


async def _handshake(port: int, origin: str | None) -> str:
    """Open a Foxglove WebSocket with ``origin`` (None: no header): its first message's op,
    or ``refused <status>``."""
    try:
        async with websockets.connect(
            f"ws://127.0.0.1:{port}",
            subprotocols=SUBPROTOCOLS,
            origin=origin,  # type: ignore[arg-type]
            open_timeout=20,
        ) as ws:
            first = await asyncio.wait_for(ws.recv(), 20)
            return str(json.loads(first)["op"])
    except websockets.exceptions.InvalidStatus as error:
        return f"refused {error.response.status_code}"


def test_a_foreign_web_origin_is_refused_and_native_and_loopback_clients_connect(
    tmp_path: Path,
) -> None:
    with running_daemon(tmp_path) as (daemon, _session):
        bridge = Bridge(daemon.port, "--allow-origin", "https://app.foxglove.dev")
        try:
            bridge.wait_ready()
            port = bridge.port
            assert asyncio.run(_handshake(port, "https://evil.example")) == "refused 403"
            assert asyncio.run(_handshake(port, "null")) == "refused 403"
            assert asyncio.run(_handshake(port, None)) == "serverInfo"
            assert asyncio.run(_handshake(port, f"http://localhost:{port}")) == "serverInfo"
            assert asyncio.run(_handshake(port, "https://app.foxglove.dev")) == "serverInfo"
            bridge.stderr.wait_for("refused a WebSocket from origin https://evil.example")
        finally:
            assert bridge.stop() == 0


SECRET = "my pin is 4321"


async def _private_session(port: int, daemon_session: Any) -> FoxgloveClient:
    """Say a secret and let a user arrive; read until a touch that came after both."""
    async with websockets.connect(f"ws://127.0.0.1:{port}", subprotocols=SUBPROTOCOLS) as ws:
        client = FoxgloveClient(ws)
        state, user = "/robots/mini/dms/state", "/robots/mini/perception/user"
        touch = "/robots/mini/perception/touch"
        ann = {"present": True, "user_id": "ann", "ready": True}
        await client.until(lambda: state in client.channels)
        await client.subscribe(state)
        put(daemon_session, "perception/user", ann)
        await client.until(lambda: user in client.channels)
        await client.subscribe(user)
        # Two states published well after the subscription show that the server has it;
        # then the user again, for the new subscription.
        sent = time.time() + 0.5
        await client.until(lambda: sum(_time(m) > sent for m in client.seen.get(state, [])) >= 2)
        put(daemon_session, "perception/user", ann)
        await client.until(
            lambda: any(m.get("user") for m in client.seen[state]) and bool(client.seen.get(user))
        )
        put(daemon_session, "perception/speech", {"text": SECRET, "confidence": 0.9})
        # The touch is put after the speech by the same session: once the bridge has
        # forwarded it, it has had the speech.
        put(daemon_session, "perception/touch", {"part": "head", "kind": "tap"})
        await client.until(lambda: touch in client.channels)
        return client


def _seen_text(client: FoxgloveClient) -> str:
    return json.dumps([client.channels, client.seen])


def test_speech_and_user_ids_are_held_back_unless_asked_for(tmp_path: Path) -> None:
    with running_daemon(tmp_path) as (daemon, session):
        bridge = Bridge(daemon.port)
        try:
            bridge.wait_ready()
            client = asyncio.run(_private_session(bridge.port, session))
        finally:
            assert bridge.stop() == 0
        assert "/robots/mini/perception/speech" not in client.channels
        assert SECRET not in _seen_text(client) and '"ann"' not in _seen_text(client)
        states = [m for m in client.seen["/robots/mini/dms/state"] if m.get("user")]
        assert states[-1]["user"]["id"] == "(hidden)"
        assert client.seen["/robots/mini/perception/user"][-1]["user_id"] == "(hidden)"

        bridge = Bridge(daemon.port, "--personal-data")
        try:
            bridge.wait_ready()
            client = asyncio.run(_private_session(bridge.port, session))
        finally:
            assert bridge.stop() == 0
        assert "/robots/mini/perception/speech" in client.channels
        assert client.seen["/robots/mini/perception/user"][-1]["user_id"] == "ann"
