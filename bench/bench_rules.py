"""Evaluations per second of the compiled ObstacleDetected rule vs the PyPI `rule-engine`.

Both decide the rule of the paper "Combining Finite State Machine and Decision-Making Tools
for Adaptable Robot Behavior" (plan / help / nothing) over the same parameter combinations
in one run. Prints one JSON object. ``--quick``: two short rounds, a smoke test.
"""

from __future__ import annotations

import argparse
import json
import random
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import rule_engine

from dms.rules import load_rules

OBSTACLE = Path(__file__).resolve().parents[1] / "dms" / "rules" / "examples" / "obstacle.dmsl"
FREE = "{10, 11, 12, 13, 17, 18, 19, 20, 21}"
PLAN = f"hearing == false or age > 80 or not (bondlevel in {{3, 4, 5}}) or not (time in {FREE})"
HELP = "batterylevel < 10 or currentbestpath == false or currentroom == favoriteroom"


def combinations(count: int, seed: int = 7) -> list[dict[str, dict[str, Any]]]:
    """Random, complete parameter sets (rule-engine cannot take missing ones)."""
    rng = random.Random(seed)
    rooms = ["kitchen", "hall", "bedroom"]
    return [
        {
            "user": {
                "hearing": rng.random() < 0.9,
                "age": rng.randint(60, 95),
                "bondlevel": rng.randint(0, 5),
                "favoriteroom": rng.choice(rooms),
            },
            "robot": {"batterylevel": rng.randint(0, 100), "currentroom": rng.choice(rooms)},
            "env": {"time": rng.randint(0, 23), "currentbestpath": rng.random() < 0.8},
        }
        for _ in range(count)
    ]


ROUNDS = 10


def rate(decide: Callable[[Any], tuple[str, ...]], inputs: list[Any], seconds: float) -> float:
    """Evaluations per second of ``decide`` over ``inputs``, for about ``seconds``."""
    done = 0
    start = time.perf_counter()
    while True:
        for item in inputs:
            decide(item)
        done += len(inputs)
        elapsed = time.perf_counter() - start
        if elapsed >= seconds:
            return done / elapsed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="two short rounds (smoke)")
    quick = parser.parse_args().quick
    rounds, seconds = (2, 0.05) if quick else (ROUNDS, 0.3)
    params = combinations(256)
    rules = load_rules([OBSTACLE])
    plan_rule = rule_engine.Rule(PLAN)
    help_rule = rule_engine.Rule(HELP)
    flat = [{**p["user"], **p["robot"], **p["env"]} for p in params]

    def dmsl(item: dict[str, dict[str, Any]]) -> tuple[str, ...]:
        return rules.evaluate("ObstacleDetected", item).activate

    def engine(item: dict[str, Any]) -> tuple[str, ...]:
        if plan_rule.matches(item):
            return ("plan",)
        if help_rule.matches(item):
            return ("help",)
        return ()

    # the same decisions, or the comparison means nothing
    assert [dmsl(p) for p in params] == [engine(f) for f in flat]
    # Interleaved rounds, best of each: a burst of load on the machine hits both alike.
    dmsl_rate = engine_rate = 0.0
    for _ in range(rounds):
        dmsl_rate = max(dmsl_rate, rate(dmsl, params, seconds))
        engine_rate = max(engine_rate, rate(engine, flat, seconds))
    print(
        json.dumps(
            {
                "dmsl_evaluations_per_s": round(dmsl_rate),
                "rule_engine_evaluations_per_s": round(engine_rate),
                "ratio": round(dmsl_rate / engine_rate, 1),
                "combinations": len(params),
                "rounds": rounds,
            }
        )
    )


if __name__ == "__main__":
    main()
