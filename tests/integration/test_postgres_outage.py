"""PostgreSQL going away for 20 s under a running daemon process, caused for real.

The daemon reaches the real PostgreSQL server through a TCP relay on 127.0.0.1 that the
test cuts: every open connection is closed and new ones are refused, as when the
database host reboots. The 2 Hz loop must not notice (no ``dms/state`` gap over
0.6 s), the activity runs written during the outage must land once the server is back,
and a kill -9 during the next outage must lose none of them after a restart.
"""

from __future__ import annotations

import contextlib
import itertools
import json
import socket
import threading
from collections.abc import Iterator
from datetime import datetime
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import pytest
import zenoh
from sqlalchemy import create_engine, text

from tests.integration.harness import Collector, DaemonProcess, client_session, free_port, put
from tests.postgres import POSTGRES_URL, fresh_schema

pytestmark = [
    pytest.mark.integration,
    pytest.mark.postgres,
    pytest.mark.skipif(POSTGRES_URL is None, reason="DMS_TEST_POSTGRES_URL is not set"),
]

ANN_READY = {"present": True, "user_id": "ann", "ready": True}


class Relay:
    """A TCP relay to the database server that can be cut and restored."""

    def __init__(self, upstream: tuple[str, int]) -> None:
        self.upstream = upstream
        self.port = free_port()
        self._pairs: list[tuple[socket.socket, socket.socket]] = []
        self._lock = threading.Lock()
        self._listener: socket.socket | None = None
        self.restore()

    def restore(self) -> None:
        listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        listener.bind(("127.0.0.1", self.port))
        listener.listen(64)
        self._listener = listener
        threading.Thread(target=self._accept, args=(listener,), daemon=True).start()

    def _accept(self, listener: socket.socket) -> None:
        while True:
            try:
                client, _ = listener.accept()
            except OSError:
                return  # cut
            try:
                server = socket.create_connection(self.upstream, timeout=5)
            except OSError:
                client.close()
                continue
            with self._lock:
                self._pairs.append((client, server))
            for a, b in ((client, server), (server, client)):
                threading.Thread(target=self._pump, args=(a, b), daemon=True).start()

    @staticmethod
    def _pump(source: socket.socket, sink: socket.socket) -> None:
        try:
            while data := source.recv(65536):
                sink.sendall(data)
        except OSError:
            pass
        finally:
            for sock in (source, sink):
                with contextlib.suppress(OSError):
                    sock.shutdown(socket.SHUT_RDWR)

    def cut(self) -> None:
        """Refuse new connections and break the open ones."""
        assert self._listener is not None
        with contextlib.suppress(OSError):  # close() alone does not wake a blocked accept()
            self._listener.shutdown(socket.SHUT_RDWR)
        self._listener.close()
        self._listener = None
        with self._lock:
            pairs, self._pairs = self._pairs, []
        for client, server in pairs:
            for sock in (client, server):
                with contextlib.suppress(OSError):
                    sock.shutdown(socket.SHUT_RDWR)
                sock.close()

    def close(self) -> None:
        if self._listener is not None:
            self.cut()


@pytest.fixture
def relayed_url() -> Iterator[tuple[Relay, str, str]]:
    """(relay, the daemon's URL through it, the direct URL), on a fresh schema."""
    assert POSTGRES_URL is not None
    parts = urlsplit(POSTGRES_URL)
    relay = Relay((parts.hostname or "127.0.0.1", parts.port or 5432))
    try:
        with fresh_schema("o") as direct:
            yield relay, direct.replace(f":{parts.port}/", f":{relay.port}/"), direct
    finally:
        relay.close()


def _t(state: dict[str, Any]) -> float:
    return datetime.fromisoformat(str(state["time"]).replace("Z", "+00:00")).timestamp()


def _runs(url: str) -> int:
    """Runs of jokes stored (the robot's own picks between the rounds are not counted)."""
    query = text("SELECT count(*) FROM activity_runs WHERE activity = 'jokes'")
    engine = create_engine(url)
    try:
        with engine.connect() as connection:
            return int(connection.execute(query).scalar_one())
    finally:
        engine.dispose()


def _spooled(state_home: Path, op: str) -> int:
    """Pending ``op`` writes in the daemon's spool file, read as the spool reads itself."""
    pending: list[str] = []
    for path in state_home.glob("dms/*.spool"):
        for line in path.read_text().splitlines():
            try:
                entry = json.loads(line)
            except ValueError:
                continue  # a line being written
            if "done" in entry:
                del pending[: int(entry["done"])]
            elif "op" in entry:
                pending.append(str(entry["op"]))
    return pending.count(op)


def _start_and_stop(session: zenoh.Session, decisions: Collector, rounds: int) -> None:
    """``rounds`` activities for ann, each started and stopped by an app: one run each."""
    for _ in range(rounds):
        put(session, "perception/user", ANN_READY)  # ann is still there
        mark = decisions.mark()
        put(session, "request", {"action": "start", "activity": "jokes", "by": "app"})
        decisions.wait_for(
            lambda d: d["action"] == "start" and d["activity"] == "jokes", start=mark
        )
        mark = decisions.mark()
        put(session, "request", {"action": "cancel", "activity": "jokes", "by": "app"})
        decisions.wait_for(
            lambda d: d["action"] == "cancel" and d["activity"] == "jokes", start=mark
        )


def test_postgres_away_for_20_s_costs_no_tick_and_no_write(
    tmp_path: Path, relayed_url: tuple[Relay, str, str], monkeypatch: pytest.MonkeyPatch
) -> None:
    relay, url, direct = relayed_url
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "state"))  # where its spool goes
    daemon = DaemonProcess(tmp_path)
    daemon.db = url
    session = client_session(daemon.port)
    try:
        daemon.start(session)
        states = Collector(session, "robots/mini/dms/state")
        decisions = Collector(session, "robots/mini/dms/decision")
        put(session, "perception/user", ANN_READY)
        states.wait_for(lambda s: (s["user"] or {}).get("id") == "ann")
        _start_and_stop(session, decisions, 2)

        relay.cut()
        cut_mark = states.mark()
        first = states.wait_for(lambda s: True, start=cut_mark)
        _start_and_stop(session, decisions, 3)  # written while the database is away
        states.wait_for(lambda s: _t(s) >= _t(first) + 20.0, start=cut_mark, timeout=60)
        window = states.messages[cut_mark:]
        relay.restore()

        gaps = [b - a for a, b in itertools.pairwise(_t(s) for s in window)]
        assert max(gaps) <= 0.6, f"longest dms/state gap {max(gaps):.3f} s during the outage"

        # every run lands once the server is back (the writer retries with backoff)
        deadline = _t(window[-1]) + 30.0
        states.wait_for(
            lambda s: _runs(direct) >= 5 or _t(s) > deadline, start=len(states.messages) - 1
        )
        assert _runs(direct) == 5

        # a kill -9 during a second outage, then a restart: nothing acknowledged is lost
        relay.cut()
        _start_and_stop(session, decisions, 2)
        # the two runs are acknowledged once they are in the fsync'd spool: then kill -9
        states.wait_for(
            lambda s: _spooled(tmp_path / "state", "record_activity") >= 2,
            start=len(states.messages) - 1,
            timeout=20,
        )
        daemon.kill()
        relay.restore()
        daemon.start(session)
        restarted = states.mark()
        states.wait_for(lambda s: _runs(direct) >= 7, start=restarted, timeout=40)
        assert _runs(direct) == 7
        assert daemon.terminate() == 0
    finally:
        daemon.kill()
        session.close()
