"""The chooser's model is retrained in the background, so an erase reaches the predictor
while the daemon runs, without blocking the decision loop."""

from __future__ import annotations

import threading
from datetime import timedelta
from pathlib import Path
from typing import Any

from sqlalchemy import text
from typer.testing import CliRunner

from dms.kernel.activity_names import ENTERTAINMENT_ACTIVITIES
from memory import ActivityChooser, PreferenceModel, ProfileStore
from memory.cli import app
from tests.memory.conftest import NOW

WAIT_S = 30.0
"""Upper bound for a background training in these tests (they wait on its thread)."""


def _with_evidence(store: ProfileStore, user: str, favorite: str, age: int = 70) -> None:
    store.get_or_create(user, NOW)
    store.update(user, NOW, age=age, hobbies="music", sex="female")
    for activity in ENTERTAINMENT_ACTIVITIES:
        store.record_feedback(user, activity, 1.0 if activity == favorite else 0.0, NOW)


def _retrained(chooser: ActivityChooser) -> PreferenceModel:
    assert chooser.retrain() is not None
    assert chooser.wait_retrained(WAIT_S)
    return chooser.model


def test_after_an_erase_a_retraining_forgets_the_user(store: ProfileStore, db_url: str) -> None:
    _with_evidence(store, "fan0", "bingo", age=99)
    for index in range(1, 6):
        _with_evidence(store, f"fan{index}", "bingo")
    chooser = ActivityChooser(PreferenceModel.train(store), store)
    before = chooser.model.training_size
    assert 99 in [features["age"] for features, _ in store.training_rows()]
    # The erase comes from the command line while the daemon holds the database.
    with store.engine.connect() as daemon_reading:
        daemon_reading.execute(text("SELECT count(*) FROM users")).scalar_one()
        result = CliRunner().invoke(app, ["erase", "fan0", "--yes", "--db", db_url])
        assert result.exit_code == 0, result.output
    assert chooser.model.training_size == before  # not learnt again yet
    after = _retrained(chooser).training_size
    assert after == before - 1
    assert sorted(features["age"] for features, _ in store.training_rows()) == [70] * 5
    assert "fan0" not in store.list_ids()


class _GatedStore(ProfileStore):
    """A real store whose training read waits for the test, and notes its thread."""

    def __init__(self, url: str) -> None:
        super().__init__(url)
        self.reading = threading.Event()
        self.go_on = threading.Event()
        self.reader: int | None = None

    def training_rows(self) -> list[tuple[dict[str, Any], dict[str, float]]]:
        self.reader = threading.get_ident()
        self.reading.set()
        assert self.go_on.wait(WAIT_S)
        return super().training_rows()


def test_retraining_runs_off_the_calling_thread_and_swaps_the_model(db_url: str) -> None:
    gated = _GatedStore(db_url)
    try:
        for index in range(3):
            _with_evidence(gated, f"fan{index}", "dance")
        old = PreferenceModel.from_seed()
        chooser = ActivityChooser(old, gated)
        assert chooser.session_ended(NOW)  # returns while the training waits
        assert gated.reading.wait(WAIT_S)
        assert gated.reader != threading.get_ident()
        assert chooser.model is old  # the old model serves until the new one is ready
        assert chooser.retrain() is None  # one training at a time
        gated.go_on.set()
        assert chooser.wait_retrained(WAIT_S)
        assert chooser.model is not old
        assert chooser.model.training_size == old.training_size + 3
    finally:
        gated.go_on.set()
        gated.close()


def test_session_ends_retrain_at_most_once_per_interval(store: ProfileStore) -> None:
    started: list[threading.Thread] = []

    def start(work: Any) -> threading.Thread:
        thread = threading.Thread(target=work, daemon=True)
        thread.start()
        thread.join(WAIT_S)
        started.append(thread)
        return thread

    chooser = ActivityChooser(PreferenceModel.from_seed(), store, retrain_every_s=600, start=start)
    assert chooser.session_ended(NOW)
    assert not chooser.session_ended(NOW + timedelta(minutes=9))
    assert chooser.session_ended(NOW + timedelta(minutes=10))
    assert len(started) == 2
    assert not ActivityChooser(PreferenceModel.from_seed()).session_ended(NOW)  # no store


def test_a_failed_retraining_keeps_the_model(store: ProfileStore) -> None:
    _with_evidence(store, "ann", "quiz")
    model = PreferenceModel.from_seed()
    chooser = ActivityChooser(model, store)
    with store.engine.begin() as connection:
        connection.execute(text("DROP TABLE activity_scores"))
    assert _retrained(chooser) is model


def test_a_chooser_that_never_retrains_keeps_its_model(tmp_path: Path) -> None:
    """The simulator's chooser: a seeded run must not depend on a training thread."""
    store = ProfileStore(f"sqlite:///{tmp_path / 'dms.db'}")
    try:
        model = PreferenceModel.from_seed()
        chooser = ActivityChooser(model, store, retrain_every_s=float("inf"))
        assert chooser.session_ended(NOW) is False
        assert chooser.model is model and chooser.wait_retrained(0)
    finally:
        store.close()
