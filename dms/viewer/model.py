"""What the live page shows, per robot, kept up to date from the bus (any thread).

The model knows no Zenoh and no web: the source (:mod:`dms.viewer.source`) calls its
``on_*`` methods with decoded JSON, and each change goes to the listeners (one per open
page) as an event ``(name, data)``. A page that connects gets :meth:`LiveModel.attach`'s
snapshot and every event after it, in order: both happen under one lock.

What daemons publish is read loosely: an unknown field is ignored and a field of the
wrong type is treated as absent, so that a newer (or a broken) daemon never stops the
viewer. The page shows every text with ``textContent``: an error may quote a hostile input.
What is kept is bounded (:mod:`dms.viewer.bounds`), and a state dated ahead of the
viewer's clock is set aside: what the viewer refuses it says on the page, as an error
whose key is ``viewer``.
"""

from __future__ import annotations

import math
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable, Mapping
from contextlib import suppress
from dataclasses import dataclass, field
from datetime import UTC, datetime
from typing import Any, get_args

from dms.kernel import keys
from dms.kernel.messages import JointName
from dms.viewer import bounds

HISTORY_S = 3600.0
"""How far back the drives chart goes."""
SAMPLE_EVERY_S = 1.0
"""At most one chart point a second per robot (the state comes twice a second)."""
MAX_DECISIONS = 200
MAX_ERRORS = 100
MAX_ROBOTS = 256
FUTURE_TOLERANCE_S = 60.0
"""A state dated further ahead of the viewer's clock is set aside (a daemon's clock gone
wrong would otherwise push the chart's hour past every point it holds)."""
NOTICE_EVERY_S = 60.0
"""The same refusal is said on the page at most this often per robot."""
RETRY_STRUCTURE_S = 3.0
"""How soon a behavior structure that did not come (or came for another activity) is asked again."""
BODY_EVERY_S = 0.25
"""At most four ``body`` events a second per robot (the joints come at every tick)."""
BODY_MOVED_RAD = 0.002
"""Joints that moved less than this since the last ``body`` event are not sent again."""
JOINT_NAMES = frozenset(get_args(JointName))
MAX_FRAME_CHARS = 200

Listener = Callable[[str, dict[str, Any]], None]
"""Called with (event name, data) under the model's lock: it must not block."""
Need = Callable[[str, str], None]
"""Called with (robot id, ``"behavior"`` or ``"agenda"``) when the model wants a query made."""


@dataclass
class RobotView:
    """One robot as the page sees it."""

    robot: str
    alive: bool = False
    since: float | None = None
    """When ``alive`` last changed (epoch seconds)."""
    tokens: set[str] = field(default_factory=set)
    """Liveliness tokens under ``robots/<id>/alive/`` other than ``dms``."""
    state: dict[str, Any] | None = None
    structure: dict[str, Any] | None = None
    """The last ``dms/behavior`` reply, or ``{"activity": name, "error": ...}``."""
    asked_for: str | None = None
    asked_at: float = -math.inf
    agenda: dict[str, Any] | None = None
    thresholds: dict[str, float] = field(default_factory=dict)
    thresholds_source: str = "none"
    """``state`` (the state carries them), ``config`` (the daemon's ``dms/config``),
    ``defaults`` (the shipped drives: the daemon told neither) or ``none``."""
    configured: dict[str, float] = field(default_factory=dict)
    """The thresholds of the daemon's ``dms/config``, once read."""
    joints: dict[str, Any] | None = None
    """The last ``robot/joints``: ``{"positions": {joint: radians}, "time": str | None}``."""
    aim: dict[str, Any] | None = None
    """The last ``aim`` command: ``{"action", "frame" (None: back to neutral), "time"}``."""
    body_sent: dict[str, Any] | None = None
    """The ``body`` event last sent to the pages (what it said, and when)."""
    samples: deque[list[Any]] = field(default_factory=deque)
    """``[time, drives, motivations, wellbeing, activity]``, one a second, the last hour."""
    decisions: bounds.BoundedLog = field(
        default_factory=lambda: bounds.BoundedLog(MAX_DECISIONS, bounds.DECISIONS_BUDGET_CHARS)
    )
    errors: bounds.BoundedLog = field(
        default_factory=lambda: bounds.BoundedLog(MAX_ERRORS, bounds.ERRORS_BUDGET_CHARS)
    )
    noticed: dict[str, float] = field(default_factory=dict)
    """When each kind of refusal was last said on the page."""
    ahead: bool = False
    """Whether the last state was dated ahead of the viewer's clock (said once per run)."""

    def to_json(self) -> dict[str, Any]:
        return {
            "robot": self.robot,
            "alive": self.alive,
            "since": self.since,
            "tokens": sorted(self.tokens),
            "state": self.state,
            "structure": self.structure,
            "agenda": self.agenda,
            "joints": self.joints,
            "aim": self.aim,
            "thresholds": self.thresholds,
            "thresholds_source": self.thresholds_source,
            "samples": list(self.samples),
            "decisions": list(self.decisions),
            "errors": list(self.errors),
        }


def robot_of(key_expr: str) -> str | None:
    """The robot id of ``robots/<id>/...``, or None."""
    parts = key_expr.split("/", 2)
    if len(parts) < 3 or parts[0] != "robots" or not keys.ROBOT_ID_RE.fullmatch(parts[1]):
        return None
    return parts[1]


def epoch(iso_time: Any, default: float) -> float:
    """Epoch seconds of an ISO-8601 time (``2026-11-22T10:00:00.500Z``), else ``default``."""
    if not isinstance(iso_time, str):
        return default
    try:
        return datetime.fromisoformat(iso_time.replace("Z", "+00:00")).timestamp()
    except ValueError:
        return default


def _numbers(value: Any) -> dict[str, float]:
    """The finite numbers of a ``{name: number}`` object (anything else dropped)."""
    if not isinstance(value, Mapping):
        return {}
    out: dict[str, float] = {}
    for name, number in value.items():
        if (
            isinstance(name, str)
            and isinstance(number, int | float)
            and not isinstance(number, bool)
            and math.isfinite(number)
        ):
            out[name] = float(number)
    return out


def _dict(value: Any) -> dict[str, Any] | None:
    return value if isinstance(value, dict) else None


def _series(value: Any) -> dict[str, float]:
    """A chart point's ``{name: number}``: the first few, their names interned."""
    numbers = _numbers(value)
    return {bounds.interned(key): numbers[key] for key in list(numbers)[: bounds.MAX_SERIES]}


_kb = bounds.size_text


def _iso(seconds: float) -> str:
    return datetime.fromtimestamp(seconds, UTC).isoformat(timespec="milliseconds")[:-6] + "Z"


class LiveModel:
    """Every robot's view, the listeners, and the queries it wants made."""

    def __init__(
        self,
        robots: Iterable[str] = (),
        default_thresholds: Mapping[str, float] | None = None,
        clock: Callable[[], float] = time.time,
    ) -> None:
        """``robots``: only these (empty: every robot on the bus). ``default_thresholds``:
        the drives' thresholds to draw when a daemon's state does not carry its own."""
        self._lock = threading.Lock()
        self._wanted = frozenset(robots)
        self._robots: dict[str, RobotView] = {}
        self._listeners: list[Listener] = []
        self._default_thresholds = dict(default_thresholds or {})
        self._clock = clock
        self.need: Need = lambda _robot, _what: None

    # ------------------------------------------------------------------ the web side

    def attach(self, listener: Listener) -> dict[str, Any]:
        """Register a page's listener; returns the snapshot its events follow."""
        with self._lock:
            self._listeners.append(listener)
            return self._snapshot()

    def detach(self, listener: Listener) -> None:
        with self._lock, suppress(ValueError):
            self._listeners.remove(listener)

    def snapshot(self) -> dict[str, Any]:
        with self._lock:
            return self._snapshot()

    def end_streams(self) -> None:
        """Tell every page's listener that the viewer stops (an event with no name)."""
        with self._lock:
            self._emit("", {})

    def agenda_due(self) -> list[str]:
        """The robots alive now, whose agenda is worth asking for."""
        with self._lock:
            return sorted(r for r, view in self._robots.items() if view.alive)

    def _snapshot(self) -> dict[str, Any]:
        return {
            "history_s": HISTORY_S,
            "now": self._clock(),
            "robots": {robot: view.to_json() for robot, view in sorted(self._robots.items())},
        }

    def _emit(self, name: str, data: dict[str, Any]) -> None:
        for listener in list(self._listeners):
            listener(name, data)

    def _view(self, robot: str) -> RobotView | None:
        """The robot's view (made on its first message), or None when it is not watched,
        or is one too many (a peer publishing under endless ids cannot fill the memory)."""
        if self._wanted and robot not in self._wanted:
            return None
        view = self._robots.get(robot)
        if view is None:
            if len(self._robots) >= MAX_ROBOTS:
                return None
            view = self._robots[robot] = RobotView(robot)
        return view

    # ------------------------------------------------------------------ the bus side

    def on_token(self, key_expr: str, alive: bool) -> None:
        """A liveliness token under ``robots/<id>/alive/`` came or went."""
        robot = robot_of(key_expr)
        if robot is None:
            return
        name = key_expr[len(keys.absolute(robot, keys.ALIVE_PREFIX)) :]
        wanted: list[str] = []
        with self._lock:
            view = self._view(robot)
            if view is None:
                return
            if name == "dms":
                if view.alive != alive:
                    view.alive, view.since = alive, self._clock()
                if alive:  # a (re)started daemon: what it runs, its settings, its agenda,
                    # and what it decided before the viewer heard it
                    view.asked_for, view.asked_at = None, -math.inf
                    view.configured = {}
                    wanted = ["config", "agenda", "decisions"]
            elif alive:
                if len(view.tokens) < bounds.MAX_TOKENS:
                    view.tokens.add(bounds.short(name, 4 * bounds.MAX_NAME_CHARS))
            else:
                view.tokens.discard(name)
            self._emit("robot", self._robot_event(view))
        for what in wanted:
            self.need(robot, what)

    @staticmethod
    def _robot_event(view: RobotView) -> dict[str, Any]:
        return {
            "robot": view.robot,
            "alive": view.alive,
            "since": view.since,
            "tokens": sorted(view.tokens),
        }

    def on_state(self, robot: str, state: Any) -> None:
        """One ``dms/state``: the page's state, and a chart point at most every second.

        A state too large to keep, or dated more than :data:`FUTURE_TOLERANCE_S` ahead
        of the viewer's clock, is set aside, and the page is told (once)."""
        if not isinstance(state, dict):
            return
        size = bounds.json_size(state)
        wanted: list[str] = []
        with self._lock:
            view = self._view(robot)
            if view is None:
                return
            now = self._clock()
            if size > bounds.MAX_MESSAGE_CHARS:
                self._notice(view, "state-size", f"a dms/state of {_kb(size)} not read", now)
                return
            if self._ahead(view, state, now):
                return
            previous = view.state or {}
            view.state = state
            sample = self._sample(view, state, now)
            self._thresholds(view, state)
            activity = _dict(state.get("activity"))
            name = activity.get("name") if activity is not None else None
            if self._wants_structure(view, name, previous, state, now):
                view.asked_for, view.asked_at = name, now
                wanted.append("behavior")
            elif name is None and view.structure is not None:
                view.structure = None
                self._emit("structure", {"robot": robot, "structure": None})
            if _user_id(previous) != _user_id(state):
                wanted.append("agenda")
            if view.joints is not None or view.aim is not None:
                self._send_body(view, now)  # what the joints' throttle held back
            self._emit(
                "state",
                {
                    "robot": robot,
                    "state": state,
                    "sample": sample,
                    "thresholds": view.thresholds,
                    "thresholds_source": view.thresholds_source,
                },
            )
        for what in wanted:
            self.need(robot, what)

    def _ahead(self, view: RobotView, state: dict[str, Any], now: float) -> bool:
        """Whether ``state`` is dated ahead of the viewer's clock (said once in a row)."""
        t = epoch(state.get("time"), now)
        if t <= now + FUTURE_TOLERANCE_S:
            view.ahead = False
            return False
        if not view.ahead:
            view.ahead = True
            stamp = bounds.short(str(state.get("time")), bounds.MAX_NAME_CHARS)
            self._report(
                view,
                f"a dms/state dated {stamp}, {t - now:.0f} s ahead of the viewer's clock, "
                "set aside (and the states after it, until one is dated within "
                f"{FUTURE_TOLERANCE_S:.0f} s of it)",
                now,
            )
        return True

    def _notice(self, view: RobotView, kind: str, text: str, now: float) -> None:
        """Say ``text`` on the page, unless the same kind was said less than
        :data:`NOTICE_EVERY_S` ago."""
        if now - view.noticed.get(kind, -math.inf) < NOTICE_EVERY_S:
            return
        view.noticed[kind] = now
        self._report(view, f"{text} (over the viewer's {_kb(bounds.MAX_MESSAGE_CHARS)})", now)

    def _report(self, view: RobotView, text: str, now: float) -> None:
        report = {"key": "viewer", "error": text, "time": _iso(now)}
        view.errors.append(report)
        self._emit("report", {"robot": view.robot, "error": report})

    def on_oversized(self, robot: str, key: str, size: int) -> None:
        """A message on ``key`` too large to be read at all (``size`` bytes)."""
        with self._lock:
            view = self._view(robot)
            if view is None:
                return
            now = self._clock()
            if key == keys.DMS_DECISION:
                self._keep_decision(view, {"oversized": size, "time": _iso(now)})
            else:
                self._notice(view, "size " + key, f"a {key} of {_kb(size)} not read", now)

    def _sample(self, view: RobotView, state: dict[str, Any], now: float) -> list[Any] | None:
        motivation = _dict(state.get("motivation")) or {}
        wellbeing = _numbers({"w": motivation.get("wellbeing")}).get("w")
        drives = _series(motivation.get("drives"))
        if not drives and wellbeing is None:
            return None
        t = epoch(state.get("time"), now)
        if view.samples and t - view.samples[-1][0] < SAMPLE_EVERY_S:
            return None
        activity = (_dict(state.get("activity")) or {}).get("name")
        name = bounds.interned(activity) if isinstance(activity, str) else None
        sample = [t, drives, _series(motivation.get("motivations")), wellbeing, name]
        view.samples.append(sample)
        while view.samples and view.samples[0][0] < t - HISTORY_S:
            view.samples.popleft()
        return sample

    def _thresholds(self, view: RobotView, state: dict[str, Any]) -> None:
        """The thresholds to draw: the state's own, else the daemon's configuration's,
        else the shipped defaults (for the drives the state names)."""
        motivation = _dict(state.get("motivation")) or {}
        drives = _numbers(motivation.get("drives"))
        published = _numbers(motivation.get("thresholds"))
        if published:
            view.thresholds, view.thresholds_source = published, "state"
        elif view.configured:
            view.thresholds, view.thresholds_source = dict(view.configured), "config"
        else:
            defaults = self._default_thresholds
            view.thresholds = {name: value for name, value in defaults.items() if name in drives}
            view.thresholds_source = "defaults" if view.thresholds else "none"

    def set_thresholds(self, robot: str, thresholds: Mapping[str, float]) -> None:
        """The thresholds of the daemon's configuration (``dms/config``)."""
        with self._lock:
            view = self._view(robot)
            if view is None:
                return
            view.configured = dict(thresholds)
            if view.state is not None:
                self._thresholds(view, view.state)

    @staticmethod
    def _wants_structure(
        view: RobotView,
        name: Any,
        previous: dict[str, Any],
        state: dict[str, Any],
        now: float,
    ) -> bool:
        """Ask ``dms/behavior`` again when the activity changed, the rules and behaviors
        were reloaded, or the active state is not in the structure held."""
        if not isinstance(name, str):
            return False
        have = view.structure.get("activity") if view.structure is not None else None
        stale = have != name or previous.get("reloads") != state.get("reloads")
        if not stale and view.structure is not None and "error" not in view.structure:
            activity = _dict(state.get("activity")) or {}
            stale = not _path_known(view.structure.get("structure"), activity.get("state"))
        if not stale:
            return False
        return view.asked_for != name or now - view.asked_at >= RETRY_STRUCTURE_S

    def on_joints(self, robot: str, message: Any) -> None:
        """One ``robot/joints``: kept (the known joints' finite numbers), and sent to the
        pages at most every :data:`BODY_EVERY_S` (the joints come at every tick)."""
        if not isinstance(message, dict):
            return
        positions = _numbers(message.get("positions"))
        positions = {name: angle for name, angle in positions.items() if name in JOINT_NAMES}
        if not positions:
            return
        stamp = message.get("time")
        with self._lock:
            view = self._view(robot)
            if view is None:
                return
            view.joints = {
                "positions": positions,
                "time": stamp[:64] if isinstance(stamp, str) else None,
            }
            self._send_body(view, self._clock())

    def on_command(self, robot: str, command: Any) -> None:
        """One ``robot/command``: only an ``aim`` is kept (the frame the robot was told to
        turn toward; ``None`` is back to neutral), the other channels are not the page's."""
        if not isinstance(command, dict) or command.get("channel") != "aim":
            return
        action = command.get("action")
        if not isinstance(action, str):
            return
        frame = (_dict(command.get("args")) or {}).get("frame")
        with self._lock:
            view = self._view(robot)
            if view is None:
                return
            now = self._clock()
            view.aim = {
                "action": action[:64],
                "frame": frame[:MAX_FRAME_CHARS] if isinstance(frame, str) else None,
                "time": now,
            }
            self._send_body(view, now)

    def _send_body(self, view: RobotView, now: float) -> None:
        """A ``body`` event, unless one went out less than :data:`BODY_EVERY_S` ago (the
        next joints or state sends what was held back) or nothing changed since."""
        sent = view.body_sent
        if sent is not None:
            if 0.0 <= now - sent["at"] < BODY_EVERY_S:
                return
            if sent["aim"] == view.aim and _same_positions(sent["joints"], view.joints):
                return
        view.body_sent = {"joints": view.joints, "aim": view.aim, "at": now}
        self._emit("body", {"robot": view.robot, "joints": view.joints, "aim": view.aim})

    def on_decision(self, robot: str, decision: Any) -> None:
        if not isinstance(decision, dict):
            return
        with self._lock:
            view = self._view(robot)
            if view is None:
                return
            decision = self._keep_decision(view, decision)
            if decision.get("action") == "start":  # the same activity again is a new run
                view.asked_for, view.asked_at = None, -math.inf
                view.structure = None

    def _keep_decision(self, view: RobotView, decision: dict[str, Any]) -> dict[str, Any]:
        """Keep ``decision`` (its short fields only, when it is too large) and send it."""
        decision, size = bounds.bounded_decision(decision)
        view.decisions.append(decision, size)
        self._emit("decision", {"robot": view.robot, "decision": decision})
        return decision

    def set_recent(self, robot: str, decisions: list[Any]) -> None:
        """The daemon's recent decisions (``dms/decisions``): those not heard yet join the
        kept ones, in time order, and the pages get the whole list again."""
        with self._lock:
            view = self._view(robot)
            if view is None:
                return
            kept = list(view.decisions)
            now = self._clock()
            recent = [bounds.bounded_decision(d)[0] for d in decisions if isinstance(d, dict)]
            merged = [d for d in recent if d not in kept] + kept
            if len(merged) == len(kept):
                return
            merged.sort(key=lambda d: epoch(d.get("time"), now))
            view.decisions.replace(merged)
            self._emit("decisions", {"robot": robot, "decisions": list(view.decisions)})

    def on_error(self, robot: str, report: Any) -> None:
        if not isinstance(report, dict):
            return
        kept = bounds.small_report(report)
        with self._lock:
            view = self._view(robot)
            if view is None:
                return
            view.errors.append(kept)
            self._emit("report", {"robot": robot, "error": kept})

    def set_structure(self, robot: str, reply: dict[str, Any]) -> None:
        """A ``dms/behavior`` reply, or ``{"error": why}`` (for the activity asked about)."""
        with self._lock:
            view = self._view(robot)
            if view is None:
                return
            size = bounds.json_size(reply)
            if size > bounds.MAX_STRUCTURE_CHARS:
                why = f"the structure is too large to draw ({_kb(size)})"
                view.structure = {"activity": view.asked_for, "error": why}
            elif "error" in reply:
                error = reply["error"]
                why = bounds.short(error) if isinstance(error, str) else "not understood"
                view.structure = {"activity": view.asked_for, "error": why}
            elif reply.get("activity") is None:
                view.structure = None
            else:
                view.structure = reply
            self._emit("structure", {"robot": robot, "structure": view.structure})

    def set_agenda(self, robot: str, agenda: dict[str, Any]) -> None:
        """``{"items": [...]}`` or ``{"error": why}``; stamped with the time it was read."""
        with self._lock:
            view = self._view(robot)
            if view is None:
                return
            view.agenda = {**bounds.small_agenda(agenda), "read": self._clock()}
            self._emit("agenda", {"robot": robot, "agenda": view.agenda})


def _same_positions(a: dict[str, Any] | None, b: dict[str, Any] | None) -> bool:
    """Whether two joint states name the same joints, none moved by :data:`BODY_MOVED_RAD`."""
    if a is None or b is None:
        return a is b
    pa, pb = a["positions"], b["positions"]
    return pa.keys() == pb.keys() and all(abs(pa[n] - pb[n]) < BODY_MOVED_RAD for n in pa)


def _user_id(state: dict[str, Any]) -> Any:
    user = _dict(state.get("user"))
    return user.get("id") if user is not None else None


def _path_known(structure: Any, path: Any) -> bool:
    """Whether every state named on the active path (``A/B,C/D``) is in the structure."""
    if not isinstance(path, str) or not path:
        return True
    names: set[str] = set()

    def walk(node: Any) -> None:
        if isinstance(node, dict):
            name = node.get("name")
            if isinstance(name, str):
                names.add(name)
            for child in node.get("states") or ():
                walk(child)

    if isinstance(structure, dict):
        walk(structure.get("root"))
    return all(part in names for branch in path.split(",") for part in branch.split("/") if part)
