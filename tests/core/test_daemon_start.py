"""The order of the daemon's start: its ready tick before any input is heard (so that it
meets nobody while it has no store), then ``alive/dms``, then the store and the agenda,
attached to the controller before its next tick.

In this process, on the in-memory bus; tests/integration/test_ready.py starts the real
daemon.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from dms.bus import InputHandler, LivelinessHandler
from dms.config import Settings
from dms.daemon import Daemon
from dms.kernel import keys
from dms.local_bus import InMemoryBus
from sim.robot import SimRobot


def test_the_ready_tick_comes_before_listening_and_the_store_after_alive(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    bus = InMemoryBus()
    daemon = Daemon(
        Settings(db=f"sqlite:///{tmp_path / 'dms.db'}", seed=1),
        print_decisions=False,
        bus=bus,
        sim_robot=lambda seed: SimRobot(rng_seed=seed),
    )
    seen: list[tuple[str, int, bool]] = []
    listen, declare_alive = bus.listen, bus.declare_alive

    def moment(name: str) -> None:
        ticks = daemon.stack.controller.counters.ticks
        seen.append((name, ticks, daemon.stack.store is not None))

    def listening(on_input: InputHandler, on_liveliness: LivelinessHandler) -> None:
        moment("listen")
        listen(on_input, on_liveliness)

    def alive() -> None:
        moment("alive")
        declare_alive()

    monkeypatch.setattr(bus, "listen", listening)
    monkeypatch.setattr(bus, "declare_alive", alive)
    try:
        daemon.start()
        moment("started")
        assert seen == [("listen", 1, False), ("alive", 1, False), ("started", 1, True)]
        deps = daemon.stack.controller.deps
        assert deps.profiles is not None and deps.agenda is daemon.stack.agenda is not None
        assert deps.chooser is daemon.stack.chooser is not None and deps.questions is not None
        assert [key for key, _ in bus.published].count(keys.DMS_STATE) == 1  # the ready tick's
    finally:
        daemon.close()
