"""The operator's look at the bus: ``dms topics``, ``dms echo KEY``, ``dms state``.

Each opens a Zenoh session that listens nowhere and connects to ``--connect`` (the
daemon's default endpoint when none is given) or to the endpoints of ``--zenoh-config``;
an endpoint that does not answer is a one-line error, exit 1.
"""

from __future__ import annotations

import json
import queue
import signal
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from types import FrameType
from typing import Annotated, Any

import typer

from dms.kernel import keys
from dms.kernel.errors import ConfigError

RobotIdOption = Annotated[str, typer.Option("--robot-id", help="Robot id.")]
ConnectOption = Annotated[
    list[str] | None,
    typer.Option(
        help="Zenoh endpoint to connect to (repeat for more).", show_default="tcp/127.0.0.1:7447"
    ),
]
ZenohConfigOption = Annotated[
    Path | None, typer.Option("--zenoh-config", help="Zenoh JSON5 configuration file.")
]


class NothingSeen(ConfigError):
    """The bus was reached, but the daemon (or the key) said nothing."""


def _robot(robot_id: str) -> str:
    if not keys.ROBOT_ID_RE.match(robot_id):
        raise ConfigError(f"--robot-id: {robot_id!r} does not match [a-z0-9_-]+")
    return robot_id


@contextmanager
def _client(robot_id: str, connect: list[str] | None, zenoh_config: Path | None) -> Iterator[Any]:
    from dms.bus import ZenohClient, make_client_config

    config = make_client_config(connect or (), zenoh_config)
    with ZenohClient(_robot(robot_id), config) as client:
        yield client


@contextmanager
def _stop_on_signals() -> Iterator[threading.Event]:
    """An event set by SIGINT or SIGTERM (the handlers are put back afterwards)."""
    stop = threading.Event()

    def on_signal(_signum: int, _frame: FrameType | None) -> None:
        stop.set()

    previous = {sig: signal.signal(sig, on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield stop
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def absolute_key(robot_id: str, key: str) -> str:
    """``KEY`` as given (``robots/...``) or under the robot (``dms/state``), checked."""
    from dms.bus import check_key_expr

    key = key.strip()
    whole = key if key.startswith("robots/") else keys.absolute(robot_id, key.lstrip("/"))
    return check_key_expr(whole)


def _decode(raw: bytes) -> tuple[bool, Any]:
    try:
        return True, json.loads(raw)
    except ValueError:
        return False, raw.decode("utf-8", errors="replace")


def _write(line: str) -> bool:
    """Print one line; False when stdout is closed (``| head``)."""
    try:
        print(line, flush=True)
    except (BrokenPipeError, ValueError, OSError):
        return False
    return True


# ---------------------------------------------------------------------- dms echo


def echo_command(
    key: Annotated[
        str,
        typer.Argument(help="Key under the robot (dms/state) or absolute (robots/mini/**)."),
    ],
    as_json: Annotated[
        bool,
        typer.Option("--json", help='One line per message: {"key", "time", "payload"}.'),
    ] = False,
    count: Annotated[
        int | None, typer.Option(min=1, help="Stop after N messages.", show_default="no limit")
    ] = None,
    timeout: Annotated[
        float | None,
        typer.Option(
            min=0.0,
            help="Stop after S seconds; exit 1 if nothing came.",
            show_default="until Ctrl-C",
        ),
    ] = None,
    robot_id: RobotIdOption = "mini",
    connect: ConnectOption = None,
    zenoh_config: ZenohConfigOption = None,
) -> None:
    """Print each message on KEY as it arrives (like ros2 topic echo), until Ctrl-C."""
    expr = absolute_key(_robot(robot_id), key)
    messages: queue.Queue[tuple[str, bytes, float]] = queue.Queue()
    seen = 0
    with _stop_on_signals() as stop, _client(robot_id, connect, zenoh_config) as client:
        client.subscribe_raw(expr, lambda k, raw: messages.put((k, raw, time.time())))
        print(f"dms: echoing {expr}; Ctrl-C stops", file=sys.stderr, flush=True)
        deadline = None if timeout is None else time.monotonic() + timeout
        while not stop.is_set() and (count is None or seen < count):
            wait = 0.2 if deadline is None else min(0.2, deadline - time.monotonic())
            if wait <= 0:
                break
            try:
                full_key, raw, when = messages.get(timeout=wait)
            except queue.Empty:
                continue
            seen += 1
            if not _write(_format_message(full_key, raw, when, as_json)):
                return
    if seen == 0 and timeout is not None and not stop.is_set():
        raise NothingSeen(f"no message on {expr} within {timeout:g} s")


def _format_message(key: str, raw: bytes, when: float, as_json: bool) -> str:
    is_json, payload = _decode(raw)
    stamp = time.strftime("%H:%M:%S", time.localtime(when)) + f".{int(when * 1000) % 1000:03d}"
    if as_json:
        iso = (
            time.strftime("%Y-%m-%dT%H:%M:%S", time.gmtime(when))
            + f".{int(when * 1000) % 1000:03d}Z"
        )
        line: dict[str, Any] = {"key": key, "time": iso, "payload": payload if is_json else None}
        if not is_json:
            line["text"] = payload
        return json.dumps(line, ensure_ascii=False)
    body = (
        json.dumps(payload, indent=2, ensure_ascii=False) if is_json else f"(not JSON) {payload!r}"
    )
    return f"--- {key}  {stamp}\n{body}"


# ---------------------------------------------------------------------- dms topics


def topics_command(
    duration: Annotated[
        float, typer.Option(min=0.1, help="How long to listen for messages, in seconds.")
    ] = 2.0,
    as_json: Annotated[bool, typer.Option("--json", help="JSON on stdout.")] = False,
    robot_id: RobotIdOption = "mini",
    connect: ConnectOption = None,
    zenoh_config: ZenohConfigOption = None,
) -> None:
    """The keys published under the robot, and its liveliness tokens.

    Keys are those seen while listening for --duration; tokens are the daemon's alive/dms
    and the input modules' alive/<key>.
    """
    robot = _robot(robot_id)
    prefix = keys.absolute(robot, "")
    counts: dict[str, list[int]] = {}
    lock = threading.Lock()

    def on_sample(full_key: str, raw: bytes) -> None:
        with lock:
            entry = counts.setdefault(full_key[len(prefix) :], [0, 0])
            entry[0] += 1
            entry[1] += len(raw)

    with _stop_on_signals() as stop, _client(robot, connect, zenoh_config) as client:
        client.subscribe_raw(prefix + "**", on_sample)
        tokens = [t[len(prefix) :] for t in client.tokens(prefix + keys.ALIVE_PREFIX + "**")]
        started = time.monotonic()
        stop.wait(duration)
        window = time.monotonic() - started
    with lock:
        seen = {key: (n, size) for key, (n, size) in sorted(counts.items())}
    if not seen and not tokens:
        raise NothingSeen(
            f"nothing under {prefix} within {window:.1f} s: no token, no message"
            f" (is the daemon running with --robot-id {robot}?)"
        )
    if as_json:
        out = {
            "robot": robot,
            "window_s": round(window, 3),
            "keys": {k: {"messages": n, "bytes": size} for k, (n, size) in seen.items()},
            "tokens": tokens,
        }
        _write(json.dumps(out, indent=2))
        return
    _write(f"robots/{robot}/ over {window:.1f} s")
    width = max([len(k) for k in seen] + [len(t) for t in tokens] + [10])
    _write("keys:" if seen else "keys: none published")
    for key, (n, size) in seen.items():
        plural = "message" if n == 1 else "messages"
        _write(f"  {key:<{width}}  {n:>5} {plural:<8}  {n / window:6.1f}/s  {size / n:7.0f} B each")
    _write("tokens:" if tokens else "tokens: none")
    for token in tokens:
        _write(f"  {token}")


# ---------------------------------------------------------------------- dms state


def state_command(
    as_json: Annotated[bool, typer.Option("--json", help="The reply as indented JSON.")] = False,
    timeout: Annotated[
        float, typer.Option(min=0.1, help="How long to wait for the reply, in seconds.")
    ] = 5.0,
    robot_id: RobotIdOption = "mini",
    connect: ConnectOption = None,
    zenoh_config: ZenohConfigOption = None,
) -> None:
    """One reply of the daemon's dms/state queryable, pretty."""
    robot = _robot(robot_id)
    with _client(robot, connect, zenoh_config) as client:
        try:
            replies = client.query(keys.DMS_STATE, timeout_s=timeout)
        except ValueError:
            raise NothingSeen(f"robots/{robot}/{keys.DMS_STATE}: the reply is not JSON") from None
    if not replies:
        raise NothingSeen(
            f"no reply from robots/{robot}/{keys.DMS_STATE} within {timeout:g} s"
            f" (is the daemon running with --robot-id {robot}?)"
        )
    ok, body = replies[0]
    if not ok:
        error = body.get("error") if isinstance(body, dict) else body
        raise NothingSeen(f"robots/{robot}/{keys.DMS_STATE}: {error}")
    if as_json:
        _write(json.dumps(body, indent=2, ensure_ascii=False))
    else:
        _write(format_state(body))


def format_state(state: dict[str, Any]) -> str:
    """A DmsState for a person: one fact a line, the drives as a small table."""

    def activity(value: Any) -> str:
        if not isinstance(value, dict):
            return "-"
        at = f", at {value.get('state')}" if value.get("state") else ""
        return f"{value.get('name')} ({value.get('manager')}), {value.get('status')}{at}"

    user = state.get("user")
    if isinstance(user, dict):
        extra = [f"proactivity {user['proactivity']}"] if user.get("proactivity") else []
        if isinstance(user.get("p_user"), int | float):
            extra.append(f"p_user {user['p_user']:.2f}")
        who = f"{user.get('id')} ({'ready' if user.get('ready') else 'not ready'})"
        who += f", {', '.join(extra)}" if extra else ""
    else:
        who = "nobody"
    motivation = _obj(state.get("motivation"))
    lines = [
        f"robot      {state.get('robot')}  tick {state.get('tick')}  {state.get('time')}",
        f"mode       {state.get('mode')}",
        f"user       {who}",
        f"activity   {activity(state.get('activity'))}",
        f"suspended  {activity(state.get('suspended'))}",
        f"robot link {state.get('robot_link', '-')}  reloads {state.get('reloads', '-')}",
        f"motivation dominant {motivation.get('dominant') or 'none'}, "
        f"wellbeing {_number(motivation.get('wellbeing'))}",
    ]
    drives = _obj(motivation.get("drives"))
    mots = _obj(motivation.get("motivations"))
    limits = _obj(motivation.get("thresholds"))
    if drives:
        width = max(len(str(name)) for name in drives)
        lines.append(f"  {'drive':<{width}}  {'level':>6}  {'motivation':>10}  {'threshold':>9}")
        for name, level in drives.items():
            lines.append(
                f"  {name:<{width}}  {_number(level):>6}  {_number(mots.get(name)):>10}"
                f"  {_number(limits.get(name)):>9}"
            )
    inputs = _obj(state.get("inputs"))
    health = ", ".join(f"{key} {status}" for key, status in inputs.items())
    lines.append(f"inputs     {health or 'none'}")
    return "\n".join(lines)


def _obj(value: Any) -> dict[str, Any]:
    return value if isinstance(value, dict) else {}


def _number(value: Any) -> str:
    if isinstance(value, bool) or not isinstance(value, int | float):
        return "-"
    return f"{value:.1f}"
