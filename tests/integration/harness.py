"""A real daemon in a subprocess and a real Zenoh session beside it, on 127.0.0.1.

The test session plays perception and a caregiver's app. Every wait is for a message
or a liveliness token, with a deadline; nothing sleeps and hopes.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, ClassVar, TypeVar

import zenoh

T = TypeVar("T")


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def client_session(port: int) -> zenoh.Session:
    """A peer connecting to ``port``, usually opened before the daemon listens there: it
    retries every 50 ms (Zenoh's default, 1 s then doubling, made each test see the
    daemon's ``alive/dms`` up to 1.3 s after it was declared)."""
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("connect/endpoints", json.dumps([f"tcp/127.0.0.1:{port}"]))
    conf.insert_json5(
        "connect/retry", "{period_init_ms: 50, period_max_ms: 50, period_increase_factor: 1}"
    )
    conf.insert_json5("listen/endpoints", "[]")
    conf.insert_json5("scouting/multicast/enabled", "false")
    return zenoh.open(conf)


class Collector:
    """Keeps every JSON message on one key expression; waits for one that matches.

    It subscribes for the test that makes it: tests/integration/conftest.py closes every
    collector after its test (on a session a module shares, the subscriber and the
    thread Zenoh runs its handler in would otherwise stay for the next tests).
    """

    _open: ClassVar[list[Collector]] = []

    def __init__(self, session: zenoh.Session, key_expr: str) -> None:
        self.messages: list[dict[str, Any]] = []
        self._cond = threading.Condition()
        self._sub = session.declare_subscriber(key_expr, self._on)
        Collector._open.append(self)

    def close(self) -> None:
        """Undeclare the subscriber (nothing to do when its session is closed already)."""
        with contextlib.suppress(zenoh.ZError):
            self._sub.undeclare()  # type: ignore[no-untyped-call]

    @classmethod
    def close_all(cls) -> None:
        """Close the collectors made since the last call."""
        while cls._open:
            cls._open.pop().close()

    def _on(self, sample: zenoh.Sample) -> None:
        with self._cond:
            self.messages.append(json.loads(sample.payload.to_bytes()))
            self._cond.notify_all()

    def wait_for(
        self, predicate: Callable[[dict[str, Any]], bool], timeout: float = 10.0, start: int = 0
    ) -> dict[str, Any]:
        """The first message from index ``start`` on that satisfies ``predicate``."""
        with self._cond:
            found: list[dict[str, Any]] = []

            def ready() -> bool:
                found[:] = [m for m in self.messages[start:] if predicate(m)][:1]
                return bool(found)

            if not self._cond.wait_for(ready, timeout):
                tail = self.messages[-5:]
                raise AssertionError(f"no matching message within {timeout}s; last: {tail}")
            return found[0]

    def wait_count(self, n: int, timeout: float = 10.0) -> list[dict[str, Any]]:
        with self._cond:
            if not self._cond.wait_for(lambda: len(self.messages) >= n, timeout):
                raise AssertionError(f"{len(self.messages)} of {n} messages within {timeout}s")
            return list(self.messages)

    def mark(self) -> int:
        with self._cond:
            return len(self.messages)


READY_TIMEOUT_S = 60.0
"""How long :func:`wait_token` waits by default (for ``alive/dms`` above all). A readiness
wait returns as soon as the token comes (about 0.6 s on a quiet 2-core machine); the
margin is for a loaded CI machine, where a 20 s wait once failed a start that took 19.9 s."""


def wait_token(session: zenoh.Session, key: str, timeout: float = READY_TIMEOUT_S) -> None:
    """Wait until liveliness token ``key`` is declared (already, or later); returns as
    soon as it is. For a token's end, see :func:`token_deleted`."""
    event = threading.Event()

    def on_token(sample: zenoh.Sample) -> None:
        if sample.kind == zenoh.SampleKind.PUT:
            event.set()

    sub = session.liveliness().declare_subscriber(key, on_token, history=True)
    try:
        assert event.wait(timeout), f"token {key} never appeared"
    finally:
        sub.undeclare()


@contextmanager
def token_deleted(
    session: zenoh.Session, key: str, timeout: float = READY_TIMEOUT_S
) -> Iterator[None]:
    """Watch liveliness token ``key``, run the body (which ends it: a signal to the
    daemon), then wait for its deletion. Watching first, since a deletion that comes
    before the watch is never seen."""
    deleted = threading.Event()

    def on_token(sample: zenoh.Sample) -> None:
        if sample.kind == zenoh.SampleKind.DELETE:
            deleted.set()

    sub = session.liveliness().declare_subscriber(key, on_token)
    try:
        yield
        assert deleted.wait(timeout), f"token {key} stayed"
    finally:
        sub.undeclare()


class DaemonProcess:
    """``dms run`` in a subprocess on a free loopback port and a SQLite file."""

    def __init__(
        self,
        tmp: Path,
        port: int | None = None,
        extra_config: str = "",
        extra_args: tuple[str, ...] = (),
        robot_id: str = "mini",
        db: str | None = None,
        session_questions: int = 0,
        new_user_after_s: float = 0.0,
    ) -> None:
        """``extra_config`` is appended inside the ``[controller]`` table (or opens its own
        tables); ``extra_args`` go after ``dms run``'s flags (``--robot zenoh``,
        ``--connect`` to a router). ``db``: a shared database (a fleet's PostgreSQL);
        ``session_questions``: the opening questions (none by default);
        ``new_user_after_s``: how long a new user waits to be stored (at once by default:
        the tests of what is stored show a user for a moment)."""
        self.port = port or free_port()
        self.extra_args = extra_args
        self.robot_id = robot_id
        self.db = db or f"sqlite:///{tmp / 'dms.db'}"
        self.config = tmp / "dms.toml"
        self.config.write_text(
            'seed = 3\n[inputs]\nstale_after_s = { "perception/user" = 30.0 }\n'
            f"[controller]\nsession_questions = {session_questions}\nquestion_every = 0\n"
            f"feedback_probability = 0.0\nnew_user_after_s = {new_user_after_s}\n" + extra_config
        )
        self.proc: subprocess.Popen[str] | None = None
        self.log = tmp / "daemon.log"

    def start(self, session: zenoh.Session) -> None:
        env = dict(os.environ, PYTHONUNBUFFERED="1")
        self._log_file = self.log.open("w")
        self.proc = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "dms.cli",
                "run",
                "--config",
                str(self.config),
                "--db",
                self.db,
                "--listen",
                f"tcp/127.0.0.1:{self.port}",
                "--robot-id",
                self.robot_id,
                *self.extra_args,
            ],
            stdout=self._log_file,
            stderr=subprocess.STDOUT,
            text=True,
            env=env,
        )
        try:
            wait_token(session, f"robots/{self.robot_id}/alive/dms")
        except AssertionError:
            self.proc.kill()
            raise AssertionError(f"daemon never became ready:\n{self.log.read_text()}") from None

    def terminate(self, timeout: float = 20.0) -> int:
        assert self.proc is not None
        self.proc.send_signal(signal.SIGTERM)
        code = self.proc.wait(timeout)
        self._log_file.close()
        if code != 0:  # shown with the failing assertion on the code
            print(f"dms run exited {code}; the end of its log:\n{self.log.read_text()[-4000:]}")
        return code

    def kill(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(10)


@contextmanager
def running_daemon(
    tmp: Path, extra_config: str = "", extra_args: tuple[str, ...] = ()
) -> Iterator[tuple[DaemonProcess, zenoh.Session]]:
    daemon = DaemonProcess(tmp, extra_config=extra_config, extra_args=extra_args)
    session = client_session(daemon.port)
    try:
        daemon.start(session)
        yield daemon, session
    finally:
        daemon.kill()
        session.close()


def put(
    session: zenoh.Session, key: str, payload: dict[str, Any] | bytes, robot: str = "mini"
) -> None:
    data = payload if isinstance(payload, bytes) else json.dumps(payload).encode()
    # BLOCK: a megabyte payload is fragmented, and under the default DROP a busy queue
    # may drop it at the sender, before the daemon could reject it.
    session.put(
        f"robots/{robot}/{key}",
        data,
        encoding=zenoh.Encoding.APPLICATION_JSON,
        congestion_control=zenoh.CongestionControl.BLOCK,
    )


def query(
    session: zenoh.Session,
    key: str,
    payload: dict[str, Any] | bytes | None = None,
    robot: str = "mini",
) -> list[tuple[bool, Any]]:
    """Every reply to one query, as (ok, body); a dict payload is sent as JSON, bytes as
    they are. Zenoh's query timeout is 10 s."""
    data = json.dumps(payload).encode() if isinstance(payload, dict) else payload
    replies = session.get(f"robots/{robot}/{key}", payload=data, timeout=10.0)
    out: list[tuple[bool, Any]] = []
    for reply in replies:
        if reply.ok is not None:
            out.append((True, json.loads(reply.ok.payload.to_bytes())))
        else:
            out.append((False, json.loads(reply.err.payload.to_bytes())))
    return out


def paced(items: Iterable[T], rate: float, stop: threading.Event | None = None) -> Iterator[T]:
    """``items`` at ``rate`` a second, for a sender that floods at a set rate; ends early
    when ``stop`` is set. (Pacing a sender, not waiting for an outcome.)"""
    stop = stop or threading.Event()
    started = time.monotonic()
    for index, item in enumerate(items):
        if stop.wait(max(0.0, started + index / rate - time.monotonic())):
            return
        yield item


def wait_subscribed(session: zenoh.Session, key: str, timeout: float = READY_TIMEOUT_S) -> None:
    """Return once some subscriber (a recorder on ``robots/mini/**``) matches a publisher
    on ``key``, a key nobody else uses: Zenoh's matching status, no guessing."""
    publisher = session.declare_publisher(key)
    matched = threading.Event()

    def on_status(status: zenoh.MatchingStatus) -> None:
        if status.matching:
            matched.set()

    publisher.declare_matching_listener(on_status)
    current = publisher.matching_status  # a MatchingStatus (the stub says bool)
    if getattr(current, "matching", current):
        matched.set()
    assert matched.wait(timeout), f"nothing subscribed to {key} within {timeout} s"


class StderrLines:
    """A process's stderr read line by line on a thread: wait for a line, never poll.

    Also keeps every line after the process ended (``text``), for failure messages."""

    def __init__(self, process: subprocess.Popen[str]) -> None:
        assert process.stderr is not None, "start the process with stderr=subprocess.PIPE"
        self.process = process
        self.lines: list[str] = []
        self._cond = threading.Condition()
        self._ended = False
        self.reader = threading.Thread(target=self._read, args=(process.stderr,), daemon=True)
        """The thread reading the output; it ends with the process."""
        self.reader.start()

    def _read(self, stream: Iterable[str]) -> None:
        for line in stream:
            with self._cond:
                self.lines.append(line.rstrip("\n"))
                self._cond.notify_all()
        with self._cond:
            self._ended = True
            self._cond.notify_all()

    def mark(self) -> int:
        with self._cond:
            return len(self.lines)

    def wait_for(
        self,
        wanted: str | Callable[[str], bool],
        timeout: float = READY_TIMEOUT_S,
        start: int = 0,
    ) -> str:
        """The first line from ``start`` on that holds ``wanted`` (or satisfies it)."""
        match = (lambda line: wanted in line) if isinstance(wanted, str) else wanted
        found: list[str] = []

        def ready() -> bool:
            found[:] = [line for line in self.lines[start:] if match(line)][:1]
            return bool(found) or self._ended

        with self._cond:
            self._cond.wait_for(ready, timeout)
            if not found:
                end = "the process ended" if self._ended else f"not within {timeout} s"
                raise AssertionError(f"no such line on stderr ({end}):\n" + self.text())
            return found[0]

    def text(self) -> str:
        """Every line so far (after the process ended: all of them)."""
        if self.process.poll() is not None:
            self.reader.join(10.0)
        with self._cond:
            return "\n".join(self.lines)
