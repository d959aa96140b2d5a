"""``dms view`` left open: it answers only requests sent to its own address, keeps a
bounded amount of whatever the bus sends it, and sets aside a state from the future.

The bus here is a test session that plays a daemon (no daemon runs); the viewer connects
to it. Every wait is for an event or a reply, with a deadline.
"""

from __future__ import annotations

import asyncio
import http.client
import json
import time
import urllib.parse
from collections.abc import Iterator
from contextlib import contextmanager
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import pytest
import zenoh

from dms.viewer.bounds import DECISIONS_BUDGET_CHARS, MAX_MESSAGE_CHARS, MAX_READ_BYTES
from dms.viewer.guard import HostGuard, allowed_hosts
from dms.viewer.model import LiveModel
from tests.integration.harness import free_port, put
from tests.integration.viewer_harness import (
    EventStream,
    running_viewer,
    token_of,
    viewer_process,
)


@contextmanager
def bus_peer() -> Iterator[tuple[zenoh.Session, int]]:
    """A Zenoh peer listening on a free loopback port (what the viewer connects to)."""
    port = free_port()
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("listen/endpoints", json.dumps([f"tcp/127.0.0.1:{port}"]))
    conf.insert_json5("scouting/multicast/enabled", "false")
    session = zenoh.open(conf)
    try:
        yield session, port
    finally:
        session.close()


def _iso(seconds: float) -> str:
    return datetime.fromtimestamp(seconds, UTC).isoformat(timespec="milliseconds")[:-6] + "Z"


def _state(robot: str, stamp: str) -> dict[str, Any]:
    return {
        "robot": robot,
        "tick": 1,
        "time": stamp,
        "mode": "motivation",
        "user": None,
        "activity": None,
        "suspended": None,
        "motivation": {
            "dominant": None,
            "drives": {"rest": 20.0},
            "motivations": {"rest": 0.0},
            "wellbeing": 80.0,
        },
        "inputs": {},
    }


def _heard(session: zenoh.Session, stream: EventStream, robot: str) -> None:
    """Publish a state until the viewer's stream shows it: its subscriptions reached us."""
    deadline = time.monotonic() + 20.0
    while True:
        put(session, "dms/state", _state(robot, _iso(time.time())), robot=robot)
        try:
            stream.wait_for("state", lambda s: s["robot"] == robot, timeout=0.5)
            return
        except AssertionError:
            if time.monotonic() > deadline:
                raise


def _request(
    url: str,
    path: str,
    host: str | None = None,
    method: str = "GET",
    origin: str | None = None,
    token: bool = True,
) -> int:
    """The status of one request to the viewer, with the ``Host`` and ``Origin`` given,
    and its token in the header unless ``token`` is False."""
    return _response(url, path, host, method, origin, token)[0]


def _response(
    url: str,
    path: str,
    host: str | None = None,
    method: str = "GET",
    origin: str | None = None,
    token: bool = True,
    headers: dict[str, str] | None = None,
) -> tuple[int, str, http.client.HTTPMessage]:
    """The status, the first 4 KB of the body and the headers of one request."""
    where = urllib.parse.urlsplit(url)
    conn = http.client.HTTPConnection(where.hostname or "", where.port, timeout=10)
    sent = dict(headers or {})
    if host is not None:
        sent["Host"] = host
    if origin is not None:
        sent["Origin"] = origin
    if token:
        sent["X-Viewer-Token"] = token_of(url)
    try:
        conn.request(method, path, headers=sent)
        response = conn.getresponse()
        streamed = response.headers.get("Content-Type", "").startswith("text/event-stream")
        body = response.read1(4096) if streamed else response.read(4096)  # a stream never ends
        return response.status, body.decode(errors="replace"), response.headers
    finally:
        conn.close()


def _snapshot(url: str) -> dict[str, Any]:
    where = urllib.parse.urlsplit(url)
    conn = http.client.HTTPConnection(where.hostname or "", where.port, timeout=10)
    try:
        conn.request("GET", "/api/snapshot", headers={"X-Viewer-Token": token_of(url)})
        return dict(json.loads(conn.getresponse().read()))
    finally:
        conn.close()


def _rss_kb(pid: int) -> int:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
    raise AssertionError("no VmRSS")


@pytest.mark.integration
def test_a_foreign_host_or_a_foreign_origin_is_refused() -> None:
    with bus_peer() as (_session, bus), running_viewer(bus) as url:
        port = urllib.parse.urlsplit(url).port or 80
        for path in ("/", "/api/snapshot", "/events", "/static/viewer.js"):
            assert _request(url, path, host=f"rebind.attacker.example:{port}") == 421, path
        assert _request(url, "/api/snapshot", host="rebind.attacker.example") == 421
        assert _request(url, "/api/snapshot", host=f"127.0.0.1:{port + 1}") == 421
        assert _request(url, "/api/snapshot", host="") == 421
        for host in (f"127.0.0.1:{port}", f"localhost:{port}", f"[::1]:{port}"):
            assert _request(url, "/api/snapshot", host=host) == 200, host
        assert _request(url, "/api/snapshot") == 200  # what a client sends by itself
        foreign = "http://rebind.attacker.example"
        assert _request(url, "/api/snapshot", method="POST", origin=foreign) == 403
        assert _request(url, "/api/snapshot", method="POST", origin="null") == 403
        own = f"http://127.0.0.1:{port}"
        assert _request(url, "/api/snapshot", method="POST", origin=own) == 405  # let through
        assert _request(url, "/api/snapshot", origin=foreign) == 200  # a read: the browser's


@pytest.mark.integration
def test_without_its_token_the_viewer_serves_only_its_static_files() -> None:
    with (
        bus_peer() as (_session, bus),
        running_viewer(bus, "--allow-host", "robot.example") as url,
    ):
        port = urllib.parse.urlsplit(url).port
        token = token_of(url)
        hosts = (f"127.0.0.1:{port}", f"localhost:{port}", f"robot.example:{port}")
        for host in hosts:
            for path in ("/", "/api/snapshot", "/events"):
                status, text, _ = _response(url, path, host=host, token=False)
                assert status == 403, (host, path, text)
                assert text.count("\n") == 1 and "dms view" in text and "token" in text, text
            assert _request(url, "/static/viewer.js", host=host, token=False) == 200
            assert _request(url, "/api/snapshot", host=host) == 200, host
        wrong = {"X-Viewer-Token": "x" + token[1:], "Cookie": f"dms-viewer-{port}=nope"}
        for name, value in wrong.items():
            status, _, _ = _response(url, "/api/snapshot", token=False, headers={name: value})
            assert status == 403, name
        # another page's token (the studio's cookie, another viewer's port) is not this one's
        other = {"Cookie": f"dms-studio-{port}={token}; dms-viewer-{port + 1}={token}"}
        assert _response(url, "/api/snapshot", token=False, headers=other)[0] == 403
        assert _response(url, f"/api/snapshot?token={token[:-1]}", token=False)[0] == 403

        status, page, headers = _response(url, f"/?token={token}", token=False)
        assert status == 200 and "viewer.js" in page
        cookie = headers["Set-Cookie"]
        assert cookie.startswith(f"dms-viewer-{port}={token};"), cookie
        assert "HttpOnly" in cookie and "SameSite=Strict" in cookie and "Path=/" in cookie
        jar = {"Cookie": cookie.split(";", 1)[0]}
        status, text, _ = _response(url, "/api/snapshot", token=False, headers=jar)
        assert status == 200 and '"robots":' in text, text[:80]
        status, text, _ = _response(url, "/events", token=False, headers=jar)
        assert status == 200 and text.startswith("retry: 1000\nevent: snapshot"), text[:80]
        status, _, headers = _response(url, "/api/snapshot", token=True)
        assert status == 200 and "Set-Cookie" not in headers  # only the URL's visit sets it


def test_the_guard_on_every_interface_takes_an_address_but_no_other_name() -> None:
    async def status(guard: HostGuard, host: str) -> int:
        sent: list[Any] = []

        async def app(_scope: Any, _receive: Any, send: Any) -> None:
            await send({"type": "http.response.start", "status": 200, "headers": []})
            await send({"type": "http.response.body", "body": b""})

        async def receive() -> Any:
            return {"type": "http.request", "body": b""}

        async def send(message: Any) -> None:
            sent.append(message)

        guard.app = app
        scope = {"type": "http", "method": "GET", "headers": [(b"host", host.encode())]}
        await guard(scope, receive, send)
        return int(sent[0]["status"])

    hosts = allowed_hosts("0.0.0.0", 8080, ["robot.local"])
    guard = HostGuard(lambda *_: None, hosts, 8080, any_address=True)  # type: ignore[arg-type]
    asked = {
        "192.168.1.20:8080": 200,
        "[fe80::1]:8080": 200,
        "robot.local:8080": 200,
        "localhost:8080": 200,
        "192.168.1.20:9090": 421,
        "evil.example:8080": 421,
    }
    for host, expected in asked.items():
        assert asyncio.run(status(guard, host)) == expected, host
    loopback = HostGuard(lambda *_: None, allowed_hosts("127.0.0.1", 8080), 8080)  # type: ignore[arg-type]
    assert asyncio.run(status(loopback, "192.168.1.20:8080")) == 421


def _big_decision(tick: int, entries: int) -> dict[str, Any]:
    preferences = [{"activity": f"activity-{i}", "score": 0.5} for i in range(entries)]
    return {
        "tick": tick,
        "time": _iso(time.time()),
        "action": "start",
        "activity": "quiz",
        "reason": "preference",
        "chosen_by": "motivation",
        "detail": None,
        "why": {"preferences": preferences},
    }


@pytest.mark.integration
def test_a_flood_of_large_decisions_keeps_the_viewer_small() -> None:
    with bus_peer() as (session, bus), viewer_process(bus) as (url, proc):
        stream = EventStream(url)
        try:
            stream.wait_for("snapshot", lambda _s: True)
            _heard(session, stream, "flood")
            before = _rss_kb(proc.pid)
            big = json.dumps(_big_decision(0, 30_000)).encode()  # 1.3 MB: not even parsed
            for _ in range(150):
                put(session, "dms/decision", big, robot="flood")
            large = _big_decision(150, 2_000)  # 86 kB: read, and kept without its why
            size = len(json.dumps(large, separators=(",", ":")))
            put(session, "dms/decision", large, robot="flood")
            stream.wait_for("decision", lambda d: d["decision"].get("tick") == 150, timeout=90)
            after = _rss_kb(proc.pid)
        finally:
            stream.close()
        kept = _snapshot(url)["robots"]["flood"]["decisions"]
    assert len(big) > MAX_READ_BYTES and MAX_MESSAGE_CHARS < size < MAX_READ_BYTES
    assert len(kept) == 151 and all(d["oversized"] == len(big) for d in kept[:-1])
    short_fields = {k: large[k] for k in ("tick", "time", "action", "activity", "reason")}
    assert kept[-1] == {
        **short_fields,
        "chosen_by": "motivation",
        "detail": None,
        "oversized": size,
    }
    assert len(json.dumps(kept)) < 50_000
    grown_mb = (after - before) / 1024
    print(f"viewer RSS {before / 1024:.0f} MB -> {after / 1024:.0f} MB after 150 decisions")
    assert grown_mb < 40, f"the viewer grew by {grown_mb:.0f} MB"


@pytest.mark.integration
def test_a_state_from_the_future_is_set_aside_and_said_once() -> None:
    with bus_peer() as (session, bus), running_viewer(bus) as url:
        stream = EventStream(url)
        try:
            stream.wait_for("snapshot", lambda _s: True)
            _heard(session, stream, "clock")
            now = time.time()
            for stamp in (_iso(now + 1), "2999-01-01T00:00:00.000Z", "2999-01-01T00:00:01.000Z"):
                put(session, "dms/state", _state("clock", stamp), robot="clock")
            last = _iso(now + 2)
            put(session, "dms/state", _state("clock", last), robot="clock")
            stream.wait_for("state", lambda s: s["state"]["time"] == last)
        finally:
            stream.close()
        view = _snapshot(url)["robots"]["clock"]
    said = [e for e in view["errors"] if e["key"] == "viewer"]
    assert len(said) == 1 and "2999-01-01T00:00:00.000Z" in said[0]["error"], said
    assert "ahead of the viewer's clock" in said[0]["error"]
    times = [sample[0] for sample in view["samples"]]
    assert len(times) >= 2 and max(times) < now + 60, times  # the chart kept its points
    assert view["state"]["time"] == last


# ---------------------------------------------------------------------- the model alone


def test_the_model_keeps_decisions_errors_and_tokens_within_bounds() -> None:
    model = LiveModel()
    detail = "d" * 9000
    for tick in range(300):  # about 9 kB each: the budget, not the count, keeps them
        model.on_decision("mini", {"tick": tick, "action": "start", "detail": detail})
    kept = model.snapshot()["robots"]["mini"]["decisions"]
    assert kept[-1]["tick"] == 299 and len(json.dumps(kept)) <= DECISIONS_BUDGET_CHARS
    assert 100 <= len(kept) < 120
    model.on_error("mini", {"key": "k" * 999, "error": "e" * 99_999, "time": "t", "x": [1] * 9})
    error = model.snapshot()["robots"]["mini"]["errors"][-1]
    assert set(error) == {"key", "error", "time"} and len(error["error"]) == 2000
    for i in range(500):
        model.on_token(f"robots/mini/alive/module{i}", True)
    assert len(model.snapshot()["robots"]["mini"]["tokens"]) == 64


def test_the_model_joins_the_daemons_recent_decisions_to_what_it_heard() -> None:
    model = LiveModel()
    events: list[tuple[str, Any]] = []
    model.attach(lambda name, data: events.append((name, data)))
    recent = [
        {"tick": t, "time": f"2026-11-22T10:00:0{t}.000Z", "action": "start"} for t in range(4)
    ]
    model.on_decision("mini", recent[3])
    model.on_decision("mini", {"tick": 9, "time": "2026-11-22T10:00:09.000Z", "action": "pause"})
    model.set_recent("mini", [*recent, "not a decision"])
    ticks = [d["tick"] for d in model.snapshot()["robots"]["mini"]["decisions"]]
    assert ticks == [0, 1, 2, 3, 9]
    assert events[-1][0] == "decisions" and len(events[-1][1]["decisions"]) == 5
    model.set_recent("mini", recent)  # nothing new: no event
    assert events[-1][0] == "decisions" and len(events) == 3


def test_the_model_sets_aside_a_state_from_the_future_once() -> None:
    clock = [datetime(2026, 11, 22, 10, 0, 0, tzinfo=UTC).timestamp()]
    model = LiveModel(clock=lambda: clock[0])
    for second, stamp in enumerate(("10:00:00", "10:00:01", None, None, "10:00:30", None)):
        clock[0] += 1
        time_of = f"2026-11-22T{stamp}.000Z" if stamp else f"2999-01-01T00:00:0{second}.000Z"
        model.on_state("mini", _state("mini", time_of))
    view = model.snapshot()["robots"]["mini"]
    assert [s[0] - view["samples"][0][0] for s in view["samples"]] == [0.0, 1.0, 30.0]
    said = [e for e in view["errors"] if e["key"] == "viewer"]
    assert len(said) == 2  # once for each run of states from the future
    assert view["state"]["time"] == "2026-11-22T10:00:30.000Z"
