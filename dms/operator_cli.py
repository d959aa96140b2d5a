"""The operator's look at the bus: ``dms topics``, ``dms echo KEY``, ``dms state``, and
``dms request ACTION`` to start, cancel, pause, resume or reload from the shell.

Each opens a Zenoh session that listens nowhere and connects to ``--connect`` (the
daemon's default endpoint when none is given) or to the endpoints of ``--zenoh-config``;
an endpoint that does not answer is a one-line error, exit 1.
"""

from __future__ import annotations

import json
import queue
import re
import signal
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from types import FrameType
from typing import Annotated, Any, Literal

import typer

from dms.kernel import keys
from dms.kernel.cli_options import ConnectOption, RobotOption, ZenohConfigOption
from dms.kernel.errors import ConfigError


class NothingSeen(ConfigError):
    """The bus was reached, but the daemon (or the key) said nothing."""


def _robot(robot_id: str) -> str:
    if not keys.ROBOT_ID_RE.fullmatch(robot_id):
        raise ConfigError(f"--robot: {robot_id!r} does not match [a-z0-9_-]+")
    return robot_id


@contextmanager
def _client(
    robot_id: str,
    connect: list[str] | None,
    zenoh_config: Path | None,
    timeout_s: float | None = None,
) -> Iterator[Any]:
    """A client session; ``timeout_s`` bounds the wait for its endpoints (default 5 s)."""
    from dms.bus import TOOL_CONNECT_TIMEOUT_S, ZenohClient, make_client_config

    wait = TOOL_CONNECT_TIMEOUT_S if timeout_s is None else max(0.1, timeout_s)
    config = make_client_config(connect or (), zenoh_config, timeout_s=wait)
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
    """``KEY`` absolute (``robots/mini/dms/state``) or under the robot (``dms/state``), with
    or without a leading ``/`` (as Foxglove and ROS name topics), checked."""
    from dms.bus import check_key_expr

    key = key.strip().lstrip("/")
    whole = key if key.startswith(ROBOTS_PREFIX) else keys.absolute(robot_id, key)
    return check_key_expr(whole)


ROBOTS_PREFIX = "robots/"


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
    robot_id: RobotOption = "mini",
    connect: ConnectOption = None,
    zenoh_config: ZenohConfigOption = None,
) -> None:
    """Print each message on KEY as it arrives (like ros2 topic echo), until Ctrl-C."""
    expr = absolute_key(_robot(robot_id), key)
    messages: queue.Queue[tuple[str, bytes, float]] = queue.Queue()
    seen = 0
    heard = KeysHeard(expr)
    with _stop_on_signals() as stop, _client(robot_id, connect, zenoh_config) as client:
        client.subscribe_raw(expr, lambda k, raw: messages.put((k, raw, time.time())))
        if heard.robot is not None:
            client.subscribe_raw(f"{ROBOTS_PREFIX}{heard.robot}/**", heard.on_sample)
        print(f"dms: echoing {expr}; Ctrl-C stops", file=sys.stderr, flush=True)
        started = time.monotonic()
        deadline = None if timeout is None else started + timeout
        hint_at: float | None = started + ECHO_HINT_AFTER_S
        while not stop.is_set() and (count is None or seen < count):
            if hint_at is not None and seen == 0 and time.monotonic() >= hint_at:
                hint_at = None  # said once
                if (hint := heard.hint(ECHO_HINT_AFTER_S)) is not None:
                    print(f"dms: {hint}", file=sys.stderr, flush=True)
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


ECHO_HINT_AFTER_S = 3.0
"""How long ``dms echo`` waits for a first message before it says that nobody publishes
an unknown key (a daemon publishes its state twice a second)."""
MAX_KEYS_HEARD = 256
PUBLISHED_KEYS = (
    *keys.INPUT_KEYS,
    keys.DMS_STATE,
    keys.DMS_DECISION,
    keys.DMS_ERRORS,
    keys.DMS_BEHAVIOR,
    keys.ROBOT_COMMAND,
)
"""The contract's keys under a robot: a key among them may just be quiet now."""


class KeysHeard:
    """The keys heard under the robot of an echoed key, to tell a typo from a quiet key."""

    def __init__(self, expr: str) -> None:
        self.expr = expr
        parts = expr.split("/", 2)
        plain = len(parts) == 3 and parts[0] == "robots" and "*" not in expr and "$" not in expr
        self.robot: str | None = parts[1] if plain else None
        """The robot of the key (None: a wildcard, which no hint is given for)."""
        self.relative = parts[2] if plain else ""
        self._lock = threading.Lock()
        self._keys: set[str] = set()

    def on_sample(self, key: str, _raw: bytes) -> None:
        relative = key.split("/", 2)[2] if key.count("/") >= 2 else key
        with self._lock:
            if len(self._keys) < MAX_KEYS_HEARD:
                self._keys.add(relative)

    def hint(self, waited_s: float) -> str | None:
        """The line for a key nobody publishes (the nearest known key); None when the key
        is the contract's or was heard, or is a wildcard."""
        from difflib import get_close_matches

        with self._lock:
            heard = set(self._keys)
        if self.robot is None or self.relative in PUBLISHED_KEYS or self.relative in heard:
            return None
        known = sorted(heard | set(PUBLISHED_KEYS))
        close = get_close_matches(self.relative, known, n=1, cutoff=0.5)
        after = f"nothing on {self.expr} after {waited_s:g} s, and it is no key the daemon uses"
        if close:
            return f"{after}: did you mean {close[0]}?"
        return f"{after}: `dms topics` lists the keys in use"


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
    key: Annotated[
        str,
        typer.Argument(help="Only the keys matching this (dms/**, /robots/mini/perception/*)."),
    ] = "**",
    duration: Annotated[
        float, typer.Option(min=0.1, help="How long to listen for messages, in seconds.")
    ] = 2.0,
    as_json: Annotated[bool, typer.Option("--json", help="JSON on stdout.")] = False,
    robot_id: RobotOption = "mini",
    connect: ConnectOption = None,
    zenoh_config: ZenohConfigOption = None,
) -> None:
    """The keys published under the robot, and its liveliness tokens.

    Keys are those seen while listening for --duration; tokens are the daemon's alive/dms
    and the input modules' alive/<key>.
    """
    robot = _robot(robot_id)
    prefix = keys.absolute(robot, "")
    expr = absolute_key(robot, key)
    counts: dict[str, list[int]] = {}
    lock = threading.Lock()

    def on_sample(full_key: str, raw: bytes) -> None:
        with lock:
            shown = full_key[len(prefix) :] if full_key.startswith(prefix) else full_key
            entry = counts.setdefault(shown, [0, 0])
            entry[0] += 1
            entry[1] += len(raw)

    with _stop_on_signals() as stop, _client(robot, connect, zenoh_config) as client:
        client.subscribe_raw(expr, on_sample)
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
    robot_id: RobotOption = "mini",
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


# ---------------------------------------------------------------------- dms request

RequestVerb = Literal["start", "cancel", "pause", "resume", "reload"]

RELOAD_ERROR_KEYS = frozenset({"rules", "behaviors", "reload"})
"""The ``dms/errors`` keys of a reload that kept the old version (docs/contract.md)."""


class Refused(ConfigError):
    """The daemon answered the request on ``dms/errors`` instead of with a decision."""


def request_command(
    action: Annotated[
        RequestVerb,
        typer.Argument(help="start ACTIVITY, cancel, pause, resume, or reload (rules, behaviors)."),
    ],
    activity: Annotated[
        str | None,
        typer.Argument(help="The activity to start (with cancel: only if it is the one running)."),
    ] = None,
    by: Annotated[
        str, typer.Option(help="Who asks: the decision's detail names it (requested by NAME).")
    ] = "cli",
    timeout: Annotated[
        float, typer.Option(min=0.1, help="How long to wait for the daemon's answer, in seconds.")
    ] = 5.0,
    as_json: Annotated[
        bool, typer.Option("--json", help="Print the decisions as JSON, one a line.")
    ] = False,
    robot_id: RobotOption = "mini",
    connect: ConnectOption = None,
    zenoh_config: ZenohConfigOption = None,
) -> None:
    """Ask the daemon to start, cancel, pause or resume an activity, or to reload, and
    print the decision that answers (exit 1 when none comes within --timeout).

    The answer: the decision naming it (requested by NAME), or a refusal on dms/errors.
    """
    robot = _robot(robot_id)
    payload = build_request(action, activity, by)
    deadline = time.monotonic() + timeout
    inbox: queue.Queue[tuple[str, Any]] = queue.Queue()
    with _client(robot, connect, zenoh_config, timeout) as client:
        for key in (keys.DMS_DECISION, keys.DMS_ERRORS, keys.DMS_STATE):
            client.subscribe(key, lambda k, body: inbox.put((k, body)))
        if not client.wait_alive(keys.ALIVE_DMS, max(0.0, deadline - time.monotonic())):
            raise NothingSeen(
                f"no daemon for robot {robot}: robots/{robot}/{keys.ALIVE_DMS} not seen within"
                f" {timeout:g} s (is it running with --robot-id {robot}?)"
            )
        before = _current_state(client, deadline)
        if action == "start" and _running(before) == activity:
            _write(f"{activity} already runs: nothing to do")
            return
        client.publish(keys.REQUEST, payload)
        answer = RequestAnswer(action, activity, by, _reloads(before))
        while (left := deadline - time.monotonic()) > 0:
            try:
                key, body = inbox.get(timeout=min(0.2, left))
            except queue.Empty:
                continue
            if answer.take(key, body, as_json):
                return
    raise NothingSeen(
        f"no answer to {action}{' ' + activity if activity else ''} from robot {robot}"
        f" within {timeout:g} s"
    )


def build_request(action: str, activity: str | None, by: str) -> dict[str, Any]:
    """The ``request`` payload (docs/contract.md), checked here so that a typo is said at
    once rather than on the daemon's ``dms/errors``."""
    from difflib import get_close_matches

    from pydantic import ValidationError

    from dms.kernel.activity_names import ACTIVITIES, NAME_PATTERN, SHIPPED, TWIN_CUTOFF
    from dms.kernel.messages import Request

    if action == "start" and activity is None:
        raise ConfigError(f"start needs an activity: one of {', '.join(ACTIVITIES)}")
    if action in ("pause", "resume", "reload") and activity is not None:
        raise ConfigError(f"{action} takes no activity (it acts on the one running)")
    if activity is not None and activity not in ACTIVITIES:
        # A near-twin of a shipped name is a typo (the loader refuses to declare one); any
        # other well-formed name may be one the daemon's behaviors folder declares: it
        # answers for it.
        close = get_close_matches(activity, SHIPPED, n=1, cutoff=TWIN_CUTOFF)
        if close or not NAME_PATTERN.match(activity):
            hint = f"; did you mean {close[0]}?" if close else f"; one of {', '.join(ACTIVITIES)}"
            raise ConfigError(f"unknown activity {activity!r}{hint}")
    wire = "reload_rules" if action == "reload" else action
    payload = {"action": wire, "activity": activity, "by": by}
    try:  # an activity unknown here is the daemon's to check
        Request.model_validate(payload if activity in ACTIVITIES else {**payload, "activity": None})
    except ValidationError as error:
        first = error.errors(include_url=False)[0]
        where = ".".join(str(part) for part in first["loc"])
        raise ConfigError(f"--{where}: {first['msg'].removeprefix('Value error, ')}") from None
    return payload if action != "reload" else {"action": wire, "by": by}


def _current_state(client: Any, deadline: float) -> dict[str, Any]:
    """The daemon's state just before the request ({} when it does not answer in time)."""
    try:
        replies = client.query(keys.DMS_STATE, timeout_s=max(0.1, deadline - time.monotonic()))
    except ValueError:
        return {}
    for ok, body in replies:
        if ok and isinstance(body, dict):
            return body
    return {}


def _running(state: dict[str, Any]) -> str | None:
    activity = state.get("activity")
    return activity.get("name") if isinstance(activity, dict) else None


def _reloads(state: dict[str, Any]) -> int | None:
    reloads = state.get("reloads")
    return reloads if isinstance(reloads, int) else None


class RequestAnswer:
    """Tells the daemon's answer to one request among what it publishes."""

    def __init__(self, action: str, activity: str | None, by: str, reloads: int | None) -> None:
        self.action, self.activity, self.by = action, activity, by
        self.reloads = reloads
        """``dms/state``'s reload count before a reload request (None: not known)."""

    def take(self, key: str, body: Any, as_json: bool) -> bool:
        """Look at one message; True once it is the final answer (printed). A refusal
        raises :class:`Refused`."""
        if not isinstance(body, dict):
            return False
        if key == keys.DMS_ERRORS:
            self._refused(body)
            return False
        if key == keys.DMS_STATE:
            return self._reloaded(body)
        if key != keys.DMS_DECISION or not self._names_us(body):
            return False
        _write(json.dumps(body, ensure_ascii=False) if as_json else format_decision_line(body))
        return self._final(body)

    def _names_us(self, decision: dict[str, Any]) -> bool:
        detail = str(decision.get("detail") or "")
        if re.search(rf"requested by {re.escape(self.by)}\b", detail):
            return True
        # a start the robot could not serve, or the answer "continue" a resume gives
        return (decision.get("action") == "fail" and decision.get("activity") == self.activity) or (
            self.action == "resume" and decision.get("action") == "resume"
        )

    def _final(self, decision: dict[str, Any]) -> bool:
        done = decision.get("action")
        if self.action == "start":
            if done == "fail" and decision.get("activity") == self.activity:
                raise Refused(f"{self.activity} did not start: {decision.get('detail')}")
            return done == "start" and decision.get("activity") == self.activity
        return done == self.action

    def _refused(self, report: dict[str, Any]) -> None:
        error, where = str(report.get("error", "")), report.get("key")
        wire = "reload_rules" if self.action == "reload" else self.action
        if where == keys.REQUEST and error.startswith(f"{wire} by {self.by}:"):
            raise Refused(f"refused: {error.split(':', 1)[1].strip()}")
        if where == keys.REQUEST and error.startswith(
            f"activity: unknown activity {self.activity!r}"
        ):
            raise Refused(f"refused: {error.split(':', 1)[1].strip()}")
        if self.action == "reload" and where in RELOAD_ERROR_KEYS:
            raise Refused(f"reload kept the old version: {where}: {error}")

    def _reloaded(self, state: dict[str, Any]) -> bool:
        reloads = _reloads(state)
        if self.action != "reload" or reloads is None:
            return False
        if self.reloads is None:
            self.reloads = reloads
            return False
        if reloads > self.reloads:
            _write(f"reloaded: rules and behaviors in force (reload {reloads})")
            return True
        return False


def format_decision_line(decision: dict[str, Any]) -> str:
    """A decision as the daemon's console prints it: time, action, activity, reason, who."""
    from dms.kernel.ids import printable  # here: dms.kernel.ids loads pydantic, --help must not

    who = f" by {decision['chosen_by']}" if decision.get("chosen_by") else ""
    what = f" {decision['activity']}" if decision.get("activity") else ""
    detail = f" ({printable(str(decision['detail']))})" if decision.get("detail") else ""
    when = str(decision.get("time", ""))[11:23]
    return f"{when} {decision.get('action', '?'):<8}{what} [{decision.get('reason')}{who}]{detail}"
