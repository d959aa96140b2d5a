"""Inputs: validation of what other processes publish, and their freshness.

:func:`parse_input` turns one raw payload into its message or raises
:class:`InputRejected` with a one-line reason. :class:`InputBoard` holds the latest
value of each state-like input and queues event inputs; it is written from the bus's
threads and read by the decision loop, so it is the only place with a lock.

Each input is *ok*, *stale* (not refreshed within its configured time) or *missing*
(never received, or its module's liveliness token went away). Stale and missing
inputs are not considered in decisions.
"""

from __future__ import annotations

import itertools
import json
import threading
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Literal, NamedTuple

from pydantic import BaseModel, ValidationError

from dms.kernel import keys
from dms.kernel.errors import DmsError
from dms.kernel.messages import INBOUND_BY_KEY, ProfileParams
from dms.rate_caps import DropTally

MAX_PAYLOAD_BYTES = 64 * 1024
"""Larger payloads are rejected before parsing: nothing legitimate is this big."""

MAX_EVENTS_QUEUED = 256
"""Event inputs beyond this many between two ticks are dropped (oldest first) and counted."""

MAX_PARAM_NAMES = 256
"""Distinct names kept per params key by default (``[inputs] max_param_names``). A name
is at most 64 characters and a text value 1,024 (:class:`ProfileParams`), so a module
that makes up new names cannot grow the daemon past a few hundred kilobytes."""

InputStatus = Literal["ok", "stale", "missing", "not_published"]


class InputRejected(DmsError):
    """A payload on an input key was not accepted; the message says why."""


def parse_input(key: str, raw: bytes) -> BaseModel:
    """Validate ``raw`` published on input ``key`` (relative); raise InputRejected."""
    model = INBOUND_BY_KEY.get(key)
    if model is None:
        raise InputRejected(f"{key} is not an input key")
    if len(raw) > MAX_PAYLOAD_BYTES:
        raise InputRejected(f"payload of {len(raw)} bytes exceeds {MAX_PAYLOAD_BYTES}")
    try:
        payload = json.loads(raw)
    except RecursionError:
        raise InputRejected("JSON nested too deeply") from None
    except (UnicodeDecodeError, ValueError) as error:
        raise InputRejected(f"not JSON: {error}") from None
    if not isinstance(payload, dict):
        raise InputRejected(f"expected a JSON object, got {type(payload).__name__}")
    try:
        if model is ProfileParams:
            return ProfileParams.from_payload(payload)
        return model.model_validate(payload)
    except ValidationError as error:
        raise InputRejected(_first_error(error)) from None
    except RecursionError:
        raise InputRejected("JSON nested too deeply") from None


def _first_error(error: ValidationError) -> str:
    first = error.errors(include_url=False)[0]
    where = ".".join(str(part) for part in first["loc"] if part != "values") or "payload"
    more = f" (and {error.error_count() - 1} more)" if error.error_count() > 1 else ""
    message = first["msg"].removeprefix("Value error, ")
    return f"{where}: {message}{more}"


_EVENT_KEYS = frozenset(keys.EVENT_INPUTS)
_OPTIONAL_KEYS = frozenset(keys.OPTIONAL_INPUTS)
_PARAMS_KEYS = frozenset({keys.PARAMS_ROBOT, keys.PARAMS_ENV})


@dataclass(slots=True)
class _Slot:
    value: BaseModel | None = None
    updated: float | None = None
    token_seen: bool = False
    token_alive: bool = False


@dataclass(frozen=True, slots=True)
class InputEvent:
    """One event input (touch, speech, screen, request, robot feedback), in arrival order."""

    key: str
    message: BaseModel
    received: float


class InputSnapshot(NamedTuple):
    """What the decision loop sees at one tick (a named tuple: immutable, and cheaper to
    make than a frozen dataclass, once a tick)."""

    values: Mapping[str, BaseModel]
    """Latest value of each state input that is ok (stale and missing ones are absent)."""
    status: Mapping[str, InputStatus]
    events: tuple[InputEvent, ...]
    robot_params: Mapping[str, Any]
    env_params: Mapping[str, Any]
    fresh: frozenset[str] = frozenset()
    """State inputs received since the last tick (a refresh counts, even if unchanged)."""


@dataclass
class InputCounters:
    """Counts for metrics and the benchmarks."""

    accepted: int = 0
    rejected: int = 0
    dropped_events: int = 0
    by_key: dict[str, int] = field(default_factory=dict)


class InputBoard:
    """The latest inputs, their freshness, and the queue of events for the next tick."""

    def __init__(
        self,
        stale_after_s: Mapping[str, float | None] | None = None,
        max_param_names: int = MAX_PARAM_NAMES,
    ) -> None:
        """``max_param_names``: distinct names kept per params key; past it, the name set
        longest ago is dropped and counted in :attr:`params_dropped` (reported once a
        second by the daemon)."""
        defaults: dict[str, float | None] = {
            keys.PERCEPTION_USER: 5.0,
            keys.PERCEPTION_OBJECTS: 5.0,
            keys.ROBOT_JOINTS: 5.0,
            keys.PARAMS_ROBOT: None,
            keys.PARAMS_ENV: None,
        }
        defaults.update(stale_after_s or {})
        self._stale_after = defaults
        self._lock = threading.Lock()
        self._slots: dict[str, _Slot] = {key: _Slot() for key in keys.INPUT_KEYS}
        self._state_slots = [
            (key, self._slots[key], defaults.get(key), key in _OPTIONAL_KEYS)
            for key in keys.INPUT_KEYS
            if key not in _EVENT_KEYS
        ]
        """(key, slot, stale limit, optional) of the state inputs, in key order (they come
        before the event inputs in ``INPUT_KEYS``, so the statuses keep its order)."""
        self._event_slots = [
            (key, self._slots[key]) for key in keys.INPUT_KEYS if key in _EVENT_KEYS
        ]
        self._events: deque[InputEvent] = deque(maxlen=MAX_EVENTS_QUEUED)
        self._robot_params: dict[str, Any] = {}
        self._env_params: dict[str, Any] = {}
        self.max_param_names = max_param_names
        self.params_dropped = DropTally()
        """Names dropped per params key for the bound, oldest first."""
        self.counters = InputCounters()
        self._fresh: set[str] = set()

    def accept(self, key: str, message: BaseModel, received: float) -> None:
        """Record a validated message (called from the bus's threads)."""
        with self._lock:
            self.counters.accepted += 1
            self.counters.by_key[key] = self.counters.by_key.get(key, 0) + 1
            slot = self._slots[key]
            slot.value, slot.updated = message, received
            self._fresh.add(key)
            if isinstance(message, ProfileParams):
                target = self._robot_params if key == keys.PARAMS_ROBOT else self._env_params
                self._merge_params(key, target, message.values)
            if key in _EVENT_KEYS:
                if len(self._events) == self._events.maxlen:
                    self.counters.dropped_events += 1
                self._events.append(InputEvent(key, message, received))

    def _merge_params(self, key: str, target: dict[str, Any], values: Mapping[str, Any]) -> None:
        """Set ``values`` in ``target`` as its newest names; drop the oldest past the bound."""
        for name, value in values.items():
            target.pop(name, None)  # set again: it becomes the newest
            target[name] = value
        over = len(target) - self.max_param_names
        if over > 0:
            for name in list(itertools.islice(target, over)):
                del target[name]
            self.params_dropped.add(key, over)

    def reject(self) -> None:
        with self._lock:
            self.counters.rejected += 1

    def liveliness(self, key: str, alive: bool) -> None:
        """A module's ``alive/<key>`` token appeared or went away."""
        with self._lock:
            slot = self._slots.get(key)
            if slot is None:
                return
            slot.token_seen = True
            slot.token_alive = alive
            if not alive:
                # What it said before it went away no longer holds.
                slot.value = None
                if key == keys.PARAMS_ROBOT:
                    self._robot_params.clear()
                elif key == keys.PARAMS_ENV:
                    self._env_params.clear()

    def take(self, monotonic_now: float) -> InputSnapshot:
        """The inputs for one tick; event inputs are handed over once.

        An input whose token went away is missing; a state input is missing until its
        first message (a robot's or an environment's parameters, which many robots never
        publish, are ``not_published`` until a message or a token comes) and stale once
        older than its limit; an event input is ok while its token stands or once a
        message came."""
        with self._lock:
            status: dict[str, InputStatus] = {}
            values: dict[str, BaseModel] = {}
            for key, slot, limit, optional in self._state_slots:
                if slot.token_seen:
                    if not slot.token_alive:
                        status[key] = "missing"
                        continue
                elif optional and slot.updated is None:
                    continue  # an optional input (objects, joints) no module provides
                elif key in _PARAMS_KEYS and slot.updated is None:
                    status[key] = "not_published"  # nobody ever said: not a fault
                    continue
                value, updated = slot.value, slot.updated
                if value is None or updated is None:
                    status[key] = "missing"
                elif limit is not None and monotonic_now - updated > limit:
                    status[key] = "stale"
                else:
                    status[key] = "ok"
                    values[key] = value
            for key, slot in self._event_slots:
                if slot.token_seen:
                    status[key] = "ok" if slot.token_alive else "missing"
                elif slot.value is not None:
                    status[key] = "ok"
                # else: an event input nobody has declared or used: not worth a line
            events: tuple[InputEvent, ...] = ()
            if self._events:
                events = tuple(
                    event for event in self._events if status.get(event.key, "ok") != "missing"
                )
                self._events.clear()
            robot = dict(self._robot_params) if keys.PARAMS_ROBOT in values else {}
            env = dict(self._env_params) if keys.PARAMS_ENV in values else {}
            fresh = frozenset(self._fresh) if self._fresh else frozenset()
            self._fresh.clear()
        return InputSnapshot(values, status, events, robot, env, fresh)
