"""A simulated visitor as a real, separate Zenoh participant (``dms run --visitor NAME``).

The visitor plays a persona against the live daemon over Zenoh, like a person with
a perception module: it declares ``alive/perception/user``, publishes
``perception/user`` at 2 Hz, listens to ``robot/command`` (what the robot says and
shows) and ``dms/decision``, and answers, taps, asks and touches through the
``perception/*`` keys. It arrives about a second after it starts, stays for the
length of the persona's first visit (a few minutes for ``demo``), leaves for a
while, and comes back, until it is stopped. It runs in a background thread on the
real clock: this is what ``make run`` shows.
"""

from __future__ import annotations

import contextlib
import logging
import random
import sys
import threading
from collections.abc import Callable
from datetime import datetime, timedelta
from typing import Any

from pydantic import ValidationError

from dms.bus import ZenohClient, make_config
from dms.config import Settings
from dms.kernel import keys
from dms.kernel.clock import Clock, RealClock
from dms.kernel.messages import Decision, RobotCommand, ScreenChoice, Speech, Touch
from sim.persona import Persona, load_persona
from sim.user import Output, SimulatedUser

log = logging.getLogger(__name__)

PERCEPTION_PERIOD_S = 0.5
POLL_S = 0.05
FIRST_ARRIVAL_S = 0.5
AWAY_S = 30.0


def describe_output(user_id: str, key: str, message: Any) -> str | None:
    """A console line for what the visitor does (not for its perception refreshes)."""
    if isinstance(message, Speech):
        return f"  {user_id} says {message.text!r}"
    if isinstance(message, ScreenChoice):
        return f"  {user_id} taps {message.choice!r} on the screen"
    if isinstance(message, Touch):
        return f"  {user_id} touches the {message.part.replace('_', ' ')}"
    return None


class Visitor:
    """One persona over Zenoh; :meth:`run` loops until :attr:`stopped` is set."""

    def __init__(
        self,
        persona: Persona,
        client: ZenohClient,
        clock: Clock,
        rng: random.Random,
        echo: Callable[[str], None] | None = None,
        stay_s: float | None = None,
        away_s: float = AWAY_S,
    ) -> None:
        self.persona = persona
        self.client = client
        self.clock = clock
        self.user = SimulatedUser(persona, rng)
        self.echo = echo
        self.stay_s = stay_s or (persona.visits[0].minutes * 60 if persona.visits else 300.0)
        self.away_s = away_s
        self.stopped = threading.Event()
        self._lock = threading.Lock()
        self.published = 0

    def _say(self, line: str) -> None:
        if self.echo is not None:
            self.echo(line)

    def _on_command(self, _key: str, payload: Any) -> None:
        try:
            command = RobotCommand.model_validate(payload)
        except ValidationError:
            return
        with self._lock:
            self.user.on_command(command, self.clock.now())

    def _on_decision(self, _key: str, payload: Any) -> None:
        try:
            decision = Decision.model_validate(payload)
        except ValidationError:
            return
        with self._lock:
            self.user.on_decision(decision, self.clock.now())

    def _publish(self, outputs: list[Output]) -> None:
        for key, message in outputs:
            self.client.publish(key, message.model_dump(mode="json"))
            self.published += 1
            line = describe_output(self.user.user_id, key, message)
            if line is not None:
                self._say(line)

    def run(self) -> None:
        """Arrive, interact, leave, come back... until stopped."""
        self.client.subscribe(keys.ROBOT_COMMAND, self._on_command)
        self.client.subscribe(keys.DMS_DECISION, self._on_decision)
        self.client.declare_token(keys.ALIVE_PREFIX + keys.PERCEPTION_USER)
        now = self.clock.now()
        next_arrival: datetime | None = now + timedelta(seconds=FIRST_ARRIVAL_S)
        leave_at: datetime | None = None
        next_perception = now
        while not self.stopped.wait(POLL_S):
            now = self.clock.now()
            with self._lock:
                if next_arrival is not None and now >= next_arrival:
                    self.user.arrive(now)
                    self._say(f"  {self.user.user_id} sits down in front of the robot")
                    next_arrival = None
                    leave_at = now + timedelta(seconds=self.stay_s)
                elif leave_at is not None and now >= leave_at:
                    self.user.leave(now)
                    self._say(f"  {self.user.user_id} leaves (back in {self.away_s:g} s)")
                    leave_at = None
                    next_arrival = now + timedelta(seconds=self.away_s)
                outputs = self.user.due(now)
                if now >= next_perception:
                    outputs.append((keys.PERCEPTION_USER, self.user.perception(now)))
                    next_perception = now + timedelta(seconds=PERCEPTION_PERIOD_S)
            self._publish(outputs)


def start_visitor(persona_name: str, settings: Settings) -> Callable[[], None]:
    """Run persona ``persona_name`` against the daemon of ``settings``; returns ``stop()``."""
    persona = load_persona(persona_name)
    client = ZenohClient(settings.robot_id, make_config(connect=settings.zenoh.listen))

    def echo(line: str) -> None:
        if settings.log_format == "json":  # every stderr line a JSON object, as the log's
            log.info(line.strip(), extra={"event": "visitor", "persona": persona.name})
            return
        with contextlib.suppress(OSError, ValueError):  # a closed console never stops the visitor
            print(line, file=sys.stderr, flush=True)

    visitor = Visitor(persona, client, RealClock(), random.Random(settings.seed), echo)
    thread = threading.Thread(target=visitor.run, name=f"visitor-{persona.name}", daemon=True)
    thread.start()

    def stop() -> None:
        visitor.stopped.set()
        thread.join(timeout=5.0)
        client.close()

    return stop
