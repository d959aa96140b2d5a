"""The daemon trains its preference model after it is ready.

Until then its chooser's beliefs start flat (an untrained model); the simulator still
trains before its first tick, so that a seeded run never depends on a thread.
"""

from __future__ import annotations

import random
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from dms.assembly import build_stack
from dms.config import Settings
from dms.daemon import Daemon
from dms.kernel.activity_names import ENTERTAINMENT_ACTIVITIES
from dms.local_bus import InMemoryBus
from memory import ActivityChooser, PreferenceModel, ProfileStore
from sim.robot import SimRobot
from tests.memory.conftest import NOW

FEATURES = {"age": 30, "hobbies": "reading", "sex": "male", "education": "university"}


def _store_fans(url: str) -> str:
    """100 stored users who like only one activity, not the seed model's favorite."""
    seed_top = PreferenceModel.from_seed().predict_ranking(FEATURES, random.Random(0))[0]
    favorite = "bingo" if seed_top != "bingo" else "dance"
    store = ProfileStore(url)
    for index in range(100):
        user = f"fan{index}"
        store.get_or_create(user, NOW)
        store.update(user, NOW, **FEATURES)
        for activity in ENTERTAINMENT_ACTIVITIES:
            store.record_feedback(user, activity, 1.0 if activity == favorite else 0.0, NOW)
    store.close()
    return favorite


def test_the_daemon_decides_untrained_until_ready_then_by_the_trained_model(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    url = f"sqlite:///{tmp_path / 'dms.db'}"
    favorite = _store_fans(url)
    bus = InMemoryBus()
    daemon = Daemon(
        Settings(db=url, seed=1),
        print_decisions=False,
        bus=bus,
        sim_robot=lambda seed: SimRobot(rng_seed=seed),
    )
    assert daemon.stack.chooser is None and daemon.stack.store is None  # opened after ready
    try:
        seed = PreferenceModel.from_seed()
        when_training: list[tuple[bool, int, bool]] = []
        retrain = ActivityChooser.retrain

        def spy(chooser: ActivityChooser) -> None:
            # alive/dms declared, nothing trained yet, beliefs flat meanwhile
            flat = chooser.model.win_scores(FEATURES) is None
            when_training.append((bus.alive, chooser.model.training_size, flat))
            retrain(chooser)

        monkeypatch.setattr(ActivityChooser, "retrain", spy)
        daemon.start()
        assert when_training == [(True, 0, True)]  # training started once, after alive/dms
        chooser = daemon.stack.chooser
        assert chooser is not None and chooser is daemon.stack.controller.deps.chooser
        assert chooser.wait_retrained(60)
        assert chooser.model.training_size > seed.training_size
        assert chooser.model.predict_ranking(FEATURES, random.Random(0))[0] == favorite
    finally:
        daemon.close()


def test_the_simulator_trains_before_its_first_tick(tmp_path: Path) -> None:
    url = f"sqlite:///{tmp_path / 'dms.db'}"
    favorite = _store_fans(url)
    stack = build_stack(
        Settings(db=url, seed=1),
        SimRobot(rng_seed=1),
        lambda command: None,
        lambda key, error: None,
        retrain=False,
    )
    try:
        assert stack.chooser is not None
        assert stack.chooser.model.predict_ranking(FEATURES, random.Random(0))[0] == favorite
        stack.when_ready()  # nothing left to do: no thread
        assert stack.chooser.wait_retrained(0)
    finally:
        stack.close()


def test_importing_the_daemon_loads_neither_scikit_learn_nor_matplotlib() -> None:
    heavy = "('sklearn', 'scipy', 'matplotlib', 'pandas')"
    code = f"import sys, dms.daemon, dms.cli; print(sorted(m for m in {heavy} if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_closing_waits_for_a_retraining_under_way(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A retraining reads the store and runs native code: closing lets it end first,
    rather than closing the store under it and exiting with its thread in LAPACK."""
    url = f"sqlite:///{tmp_path / 'dms.db'}"
    entered, release = threading.Event(), threading.Event()
    train = PreferenceModel.train

    def held_train(store: ProfileStore) -> PreferenceModel:
        entered.set()
        assert release.wait(60)
        return train(store)

    monkeypatch.setattr(PreferenceModel, "train", held_train)
    daemon = Daemon(
        Settings(db=url, seed=1),
        print_decisions=False,
        bus=InMemoryBus(),
        sim_robot=lambda seed: SimRobot(rng_seed=seed),
    )
    daemon.start()
    chooser = daemon.stack.chooser
    assert chooser is not None
    assert entered.wait(60)
    closer = threading.Thread(target=daemon.close)
    closer.start()
    closer.join(0.5)
    assert closer.is_alive()  # still waiting for the training
    release.set()
    closer.join(60)
    assert not closer.is_alive() and chooser.wait_retrained(0)
    assert chooser.model.training_size > 0  # it finished, from the store still open
