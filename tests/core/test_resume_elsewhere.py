"""Sessions move with the person; what a session end cut is resumed
at the next robot only when the configuration asks for it.

Two robot stacks (real controllers on virtual clocks, the simulated Mini) share one
real SQLite file, as a fleet shares its database. Ann plays the quiz at the hall and
walks away mid-game: the hall ends her session (``user_left``) and records the quiz as
cut. Half a minute later the garden sees her.
"""

from __future__ import annotations

from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

from dms.config import Settings
from dms.kernel import keys
from dms.kernel.messages import Request, UserPerception
from sim.harness import Simulation

START = datetime(2026, 11, 24, 10, 0, tzinfo=UTC)
ANN = UserPerception(present=True, user_id="ann", ready=True, engagement=0.8)


def _robot(db: Path, robot_id: str, start: datetime, **controller: Any) -> Simulation:
    settings = Settings.model_validate(
        {
            "robot_id": robot_id,
            "db": f"sqlite:///{db}",
            "controller": {
                "session_questions": 0,
                "question_every": 0,
                "feedback_probability": 0.0,
                **controller,
            },
        }
    )
    return Simulation(settings, seed=3, start=start)


def _quiz_cut_at_the_hall(db: Path) -> datetime:
    """Ann asks the hall for the quiz, then leaves while it runs; when she left."""
    with _robot(db, "hall", START) as hall:
        hall.presence = ANN
        hall.feed(keys.PERCEPTION_USER, ANN)
        hall.run_for(2)
        hall.feed(keys.REQUEST, Request(action="start", activity="quiz", by="ann"))
        hall.run_for(20)
        assert hall.controller.current is not None and hall.controller.current.name == "quiz"
        hall.unseat()
        hall.run_for(6)  # perception/user's stale limit, then the session ends
        left = [d for d in hall.decisions if d.decision.reason == "user_left"]
        assert [d.decision.activity for d in left] == ["quiz"], hall.decisions[-3:]
        return hall.now()


def _first_start(robot: Simulation) -> tuple[str | None, str]:
    robot.presence = ANN
    robot.feed(keys.PERCEPTION_USER, ANN)
    robot.run_for(5)
    starts = [d.decision for d in robot.decisions if d.decision.action == "start"]
    ann = [d for d in starts if d.chosen_by in ("user", "robot")]
    assert ann, f"nothing started for Ann: {robot.decisions[-5:]}"
    return ann[0].activity, ann[0].reason


def test_by_default_the_next_robot_does_not_carry_on(tmp_path: Path) -> None:
    left = _quiz_cut_at_the_hall(tmp_path / "fleet.db")
    with _robot(tmp_path / "fleet.db", "garden", left + timedelta(seconds=30)) as garden:
        activity, reason = _first_start(garden)
        assert reason != "resumed", (activity, reason)


def test_when_asked_the_next_robot_resumes_the_cut_activity(tmp_path: Path) -> None:
    left = _quiz_cut_at_the_hall(tmp_path / "fleet.db")
    start = left + timedelta(seconds=30)
    with _robot(tmp_path / "fleet.db", "garden", start, resume_cut_within_s=120) as garden:
        assert _first_start(garden) == ("quiz", "resumed")
        resumed = next(d.decision for d in garden.decisions if d.decision.reason == "resumed")
        assert resumed.chosen_by == "user" and "left" in (resumed.detail or "")


def test_a_cut_older_than_the_window_is_not_resumed(tmp_path: Path) -> None:
    left = _quiz_cut_at_the_hall(tmp_path / "fleet.db")
    start = left + timedelta(seconds=300)
    with _robot(tmp_path / "fleet.db", "garden", start, resume_cut_within_s=120) as garden:
        assert _first_start(garden)[1] != "resumed"


def test_the_cut_run_does_not_count_as_a_dislike(tmp_path: Path) -> None:
    _quiz_cut_at_the_hall(tmp_path / "fleet.db")
    with _robot(tmp_path / "fleet.db", "garden", START + timedelta(hours=1)) as garden:
        store = garden.stack.store
        assert store is not None
        run = store.last_run("ann")
        assert run is not None and run["activity"] == "quiz" and run["outcome"] == "cut"
        score = store.get("ann").scores.get("quiz")
        assert score is None or score.cancellations == 0
