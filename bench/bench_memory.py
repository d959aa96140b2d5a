"""Benchmark: how well the robot learns what users like, and how fast profiles load.

1. Kendall's tau between the predicted and the true ranking of the 8 entertainment
   activities for simulated personas (``memory.seed_data``, a seed the shipped data
   was not made from): from features alone (label ranking), then after 1, 5 and 20
   sessions of 4 activities each, chosen by ``ActivityChooser``, where the persona
   cancels activities it dislikes, completes the others and answers "how much did you
   like it?" with probability 0.5. Target: mean tau >= 0.5 after 5 sessions.
   The random ranking (no features) is the baseline.
2. Profile load (``ProfileStore.get``) with 10,000 users stored in a SQLite file.
   Target: p99 <= 5 ms.
3. Profile write (``write_ms_mean``, ``write_ms_p99``): the daemon's mix of writes, each
   with a ``write_id`` (a session started and ended, an activity run, feedback, an
   interaction, an initiative, a field update, an answer), 3 users, a SQLite file in
   /dev/shm so that the figure is the code's, not the disk's fsync.

    .venv/bin/python bench/bench_memory.py [--personas N] [--users N] [--quick]
"""

from __future__ import annotations

import argparse
import json
import random
import statistics
import tempfile
import time
import uuid
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

from sqlalchemy.orm import Session

from memory import ActivityChooser, PreferenceModel, ProfileStore
from memory.models import ActivityScoreRow, UserRow
from memory.seed_data import SimulatedPersona, make_personas

START = datetime(2026, 11, 23, 10, 0, tzinfo=UTC)
ACTIVITIES_PER_SESSION = 4
FEEDBACK_PROBABILITY = 0.5
CANCEL_BELOW = 0.35
CHECKPOINTS = (1, 5, 20)


def tau(predicted: list[str], truth: list[str]) -> float:
    """Kendall's tau between two rankings of the same activities."""
    position = {name: index for index, name in enumerate(truth)}
    order = [position[name] for name in predicted]
    pairs = concordant = 0
    for i in range(len(order)):
        for j in range(i + 1, len(order)):
            pairs += 1
            concordant += 1 if order[i] < order[j] else -1
    return concordant / pairs


def simulate(
    store: ProfileStore,
    chooser: ActivityChooser,
    persona: SimulatedPersona,
    user: str,
    rng: random.Random,
) -> dict[str, float]:
    """Sessions with one persona; tau of the blended ranking at each checkpoint."""
    store.get_or_create(user, START)
    profile = store.update(user, START, **persona.features)
    now = START
    out: dict[str, float] = {}
    truth = persona.ranking()
    for session in range(1, max(CHECKPOINTS) + 1):
        session_id = store.start_session(user, now)
        last: str | None = None
        for _ in range(ACTIVITIES_PER_SESSION):
            name = chooser.choose(profile, rng, exclude={last} if last else ()).activity
            liking = persona.liking[name]
            cancelled = liking < CANCEL_BELOW and rng.random() < 0.8
            ended = now + timedelta(minutes=2 if cancelled else 6)
            profile = store.record_activity(
                user,
                name,
                now,
                ended,
                "cancelled" if cancelled else "completed",
                "robot",
                cancelled,
                session_id,
            )
            now = ended
            if not cancelled and rng.random() < FEEDBACK_PROBABILITY:
                score = min(1.0, max(0.0, liking + rng.gauss(0.0, 0.1)))
                profile = store.record_feedback(user, name, round(score * 4) / 4, now)
            last = name
        store.end_session(session_id, now)
        now += timedelta(days=1)
        if session in CHECKPOINTS:
            out[str(session)] = tau(chooser.ranking(profile, rng), truth)
    return out


def learning(personas: int, seed: int) -> dict[str, Any]:
    rng = random.Random(seed)
    people = make_personas(personas, seed=seed)
    model = PreferenceModel.from_seed()
    features_only = [tau(model.predict_ranking(p.features, rng), p.ranking()) for p in people]
    random_baseline = [tau(model.predict_ranking({}, rng), p.ranking()) for p in people]
    folder = Path("/dev/shm") if Path("/dev/shm").is_dir() else None
    with tempfile.TemporaryDirectory(dir=folder) as tmp:
        store = ProfileStore(f"sqlite:///{Path(tmp) / 'bench.db'}")
        chooser = ActivityChooser(model, store)
        runs = [simulate(store, chooser, p, f"p{i}", rng) for i, p in enumerate(people)]
        store.close()
    return {
        "personas": personas,
        "tau_random": round(statistics.fmean(random_baseline), 3),
        "tau_features_only": round(statistics.fmean(features_only), 3),
        **{
            f"tau_after_{n}_sessions": round(statistics.fmean(run[str(n)] for run in runs), 3)
            for n in CHECKPOINTS
        },
    }


def load_time(users: int, loads: int, seed: int) -> dict[str, Any]:
    rng = random.Random(seed)
    with tempfile.TemporaryDirectory() as tmp:
        url = f"sqlite:///{Path(tmp) / 'dms.db'}"
        store = ProfileStore(url)
        with Session(store.engine) as session, session.begin():
            for index in range(users):
                user_id = f"user{index:05d}"
                session.add(
                    UserRow(
                        user_id=user_id,
                        created_at=START,
                        updated_at=START,
                        name=f"User {index}",
                        age=rng.randint(60, 95),
                        sex="female",
                        interaction_style="voice",
                        proactivity="unknown",
                        proactivity_confidence=0.0,
                        attributes={"hobbies": "music", "lives_alone": True},
                        voice_failures=0,
                        screen_failures=0,
                        initiative_taken=0,
                        initiative_offered=0,
                    )
                )
                for activity in ("quiz", "dance", "news"):
                    session.add(
                        ActivityScoreRow(
                            user_id=user_id,
                            activity=activity,
                            feedback_sum=1.5,
                            feedback_count=2,
                            completions=3,
                            cancellations=1,
                        )
                    )
        store.close()
        store = ProfileStore(url)  # a daemon start: cold connections
        times = []
        for _ in range(loads):
            user_id = f"user{rng.randrange(users):05d}"
            began = time.perf_counter()
            store.get(user_id)
            times.append((time.perf_counter() - began) * 1000)
        store.close()
    times.sort()
    return {
        "users": users,
        "loads": loads,
        "load_ms_p50": round(times[len(times) // 2], 3),
        "load_ms_p99": round(times[int(len(times) * 0.99) - 1], 3),
        "load_ms_max": round(times[-1], 3),
    }


def write_time(rounds: int) -> dict[str, Any]:
    times: list[float] = []

    def timed(call: Any, *args: Any, **kwargs: Any) -> Any:
        began = time.perf_counter()
        answer = call(*args, **kwargs)
        times.append((time.perf_counter() - began) * 1000)
        return answer

    folder = Path("/dev/shm") if Path("/dev/shm").is_dir() else None
    with tempfile.TemporaryDirectory(dir=folder) as tmp:
        store = ProfileStore(f"sqlite:///{Path(tmp) / 'writes.db'}")
        users = ("ann", "bob", "cid")
        for user_id in users:
            store.get_or_create(user_id, START)
        for index in range(rounds):
            now, user_id = START + timedelta(minutes=index), users[index % 3]

            def once() -> str:
                return uuid.uuid4().hex

            session_id = timed(store.start_session, user_id, now, write_id=once())
            timed(
                store.record_activity,
                *(user_id, "quiz", now, now, "completed", "model", False, session_id),
                write_id=once(),
            )
            timed(store.record_feedback, user_id, "quiz", 0.7, now, write_id=once())
            timed(store.record_interaction, user_id, "voice", index % 2 == 0, now, write_id=once())
            timed(store.record_initiative, user_id, index % 3 == 0, now, write_id=once())
            timed(store.update, user_id, now, write_id=once(), volume=0.5, hobby=f"h{index % 5}")
            timed(store.record_answer, user_id, "name", "Ann", now, write_id=once())
            timed(store.end_session, session_id, now)
        store.close()
    times.sort()
    return {
        "writes": len(times),
        "write_ms_mean": round(statistics.fmean(times), 3),
        "write_ms_p99": round(times[int(len(times) * 0.99) - 1], 3),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--personas", type=int, default=40)
    parser.add_argument("--users", type=int, default=10_000)
    parser.add_argument("--loads", type=int, default=2_000)
    parser.add_argument("--seed", type=int, default=99)
    parser.add_argument("--write-rounds", type=int, default=300)
    parser.add_argument(
        "--quick", action="store_true", help="5 personas, 300 users, 20 write rounds (smoke)"
    )
    args = parser.parse_args()
    if args.quick:
        args.personas, args.users, args.loads, args.write_rounds = 5, 300, 100, 20
    began = time.perf_counter()
    result = {
        **learning(args.personas, args.seed),
        **load_time(args.users, args.loads, args.seed),
        **write_time(args.write_rounds),
    }
    result["targets_met"] = result["tau_after_5_sessions"] >= 0.5 and result["load_ms_p99"] <= 5.0
    result["wall_s"] = round(time.perf_counter() - began, 1)
    print(json.dumps(result))


if __name__ == "__main__":
    main()
