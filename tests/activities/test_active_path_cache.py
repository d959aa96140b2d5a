"""The active path is kept between status changes (issue 14): it must never be stale.

``Node.active_path`` is read several times a tick (the manager's reply, the
controller's state) and worked out again only when a status or a machine's current
state changed. These tests compare it, at every tick, with the path walked afresh:
through every shipped activity, paused, resumed and preempted, and through a
simulated session with its cancels, cleanups and reminders.
"""

from __future__ import annotations

import random
from datetime import timedelta

import pytest

from activities import Activity, BehaviorLibrary
from activities.engine import Node, Status
from dms.kernel.activity_names import ACTIVITIES
from sim.harness import Simulation
from sim.persona import load_persona
from sim.user import SimulatedUser
from tests.activities.conftest import Bench


def walked(node: Node) -> str:
    """The active path as the engine computed it before it was kept."""
    parts = []
    for child in node.active_children():
        if child.status is Status.RUNNING:
            below = walked(child)
            parts.append(f"{child.name}/{below}" if below else child.name)
    return ",".join(parts)


def check(activity: Activity) -> None:
    assert activity.state_path == walked(activity.root)


@pytest.mark.parametrize("name", sorted(ACTIVITIES))
def test_every_shipped_activity_paused_resumed_and_preempted(
    shipped: BehaviorLibrary, name: str
) -> None:
    bench = Bench(shipped, seed=3)
    activity = bench.start(bench.create(name))
    check(activity)
    for tick in range(600):
        bench.now += timedelta(seconds=0.5)
        bench.expression.update(bench.now)
        if tick == 20:
            activity.pause(bench.now)
        elif tick == 30:
            activity.resume(bench.now)
        elif tick == 200:
            activity.preempt(bench.now, 5.0)
        activity.tick(bench.now)
        check(activity)
        if activity.finished:
            break


def test_a_simulated_session_never_sees_a_stale_path() -> None:
    with Simulation(seed=2) as sim:
        seen: list[str] = []

        def on_tick(_record: object) -> None:
            for manager in sim.controller.managers.values():
                running = manager.activity
                for activity in (running, *manager.winding_down):
                    if activity is not None:
                        check(activity)
                        seen.append(activity.state_path)

        sim.tick_listeners.append(on_tick)
        sim.seat(SimulatedUser(load_persona("carmen"), random.Random(2)))
        sim.run_for(1200)
    assert len(set(seen)) > 10  # many states were visited
