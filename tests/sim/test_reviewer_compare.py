"""``dms sim compare`` as a skeptical reviewer types it: the paper's choice against the
baselines that could beat it, on participants the learner was not trained on, over five
visits, in a process of its own."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from typing import Any

import pytest

ENV = {k: v for k, v in os.environ.items() if not k.startswith("DMS_")}


def compare(baseline: str) -> dict[str, Any]:
    args = [sys.executable, "-m", "dms.cli", "sim", "compare", "--chooser-a", baseline]
    args += ["--chooser-b", "dms", "--seeds", "0-5", "--population", "heldout", "--json"]
    args += ["--repeat", "5", "--sessions", "4", "--minutes", "8"]
    ran = subprocess.run(args, capture_output=True, text=True, timeout=300, env=ENV)
    assert ran.returncode == 0, ran.stderr[-2000:]
    out: dict[str, Any] = json.loads(ran.stdout)
    assert [visit["visit"] for visit in out["visits"]] == [1, 2, 3, 4, 5]
    for visit in out["visits"]:
        assert set(visit["metrics"]) == set(out["metrics"])  # every metric, every visit
    return out


def liking(part: dict[str, Any]) -> dict[str, Any]:
    found: dict[str, Any] = part["metrics"]["robot_choice_liking"]
    return found


@pytest.mark.integration
def test_the_papers_choice_learns_past_one_favourite_for_everyone() -> None:
    out = compare("popular")
    last = liking(out["visits"][-1])
    assert last["ci"][0] > 0.0, last  # dms - popular, the interval above 0 by visit 5
    assert last["diff"] > liking(out["visits"][0])["diff"], out["visits"]  # and it grew


@pytest.mark.integration
def test_the_greedy_baseline_is_the_papers_policy_within_the_noise() -> None:
    out = compare("greedy")
    pooled = liking(out)
    assert pooled["ci"][0] <= 0.0 <= pooled["ci"][1], pooled
    assert abs(pooled["diff"]) < 0.03, pooled
