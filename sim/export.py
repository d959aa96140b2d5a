"""Raw data of a study or long-term run, for a researcher's own analysis (``--out DIR``).

- ``sessions.csv``: one row per session: who, which visit, the eight Table 4 metrics
  (empty where a session has none, e.g. no activity ended), the failures, the cancels of
  robot-chosen activities and Kendall's tau of the daemon's ranking after the session;
- ``decisions.csv``: every decision taken while a participant was there, with the
  session, the seconds since the participant sat down, and ``why`` (the decision's
  explanation as JSON, when the daemon gives one; empty otherwise);
- ``table4.png``: per metric, the paper's mean ± SD beside the simulation's;
- ``adaptation.png`` (participants coming back, ``--repeat`` of 2 or more): Kendall's
  tau of the daemon's ranking against each participant's true one, and the cancels of
  robot-chosen activities, by visit (mean over participants, with a 95 % interval).

Written when a run ends, so a researcher can rerun the numbers without rerunning the
simulation.
"""

from __future__ import annotations

import csv
import json
import math
import statistics
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from sim.study import (
    LABELS,
    METRICS,
    PAPER,
    DecisionRow,
    SessionMetrics,
    adaptation,
    session_value,
)

SESSION_COLUMNS: tuple[str, ...] = (
    "session",
    "participant",
    "visit",
    *METRICS,
    "activity_not_loaded",
    "speech_recognition_errors",
    "user_not_answering",
    "other",
    "robot_choice_cancels",
    "kendall_tau",
)
DECISION_COLUMNS: tuple[str, ...] = (
    "session",
    "participant",
    "visit",
    "t",
    "time",
    "tick",
    "action",
    "activity",
    "manager",
    "reason",
    "chosen_by",
    "detail",
    "why",
)


def write_all(
    out: Path, sessions: Sequence[SessionMetrics], decisions: Sequence[DecisionRow]
) -> list[Path]:
    """``sessions.csv``, ``decisions.csv``, ``table4.png`` and, when participants came
    back, ``adaptation.png`` into ``out`` (created)."""
    out.mkdir(parents=True, exist_ok=True)
    paths = [out / "sessions.csv", out / "decisions.csv", out / "table4.png"]
    write_sessions(paths[0], sessions)
    write_decisions(paths[1], decisions)
    plot_table4(paths[2], sessions)
    if max((s.visit for s in sessions), default=1) > 1:
        paths.append(out / "adaptation.png")
        plot_adaptation(paths[3], sessions)
    return paths


def _cell(value: object) -> object:
    if value is None:
        return ""
    if isinstance(value, float):
        return round(value, 4)
    return value


def write_sessions(path: Path, sessions: Sequence[SessionMetrics]) -> None:
    """One row per session (see the module's docstring)."""
    with path.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(SESSION_COLUMNS)
        for number, s in enumerate(sessions, start=1):
            row: list[object] = [number, s.participant, s.visit]
            row += [session_value(s, key) for key in METRICS]
            row += [s.not_loaded, s.misrecognized, s.unanswered, s.other_failures]
            row += [s.robot_choice_cancels, s.kendall_tau]
            writer.writerow([_cell(value) for value in row])


def write_decisions(path: Path, rows: Sequence[DecisionRow]) -> None:
    """Every decision, one a row; ``why`` is JSON (empty when the decision has none)."""
    with path.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(DECISION_COLUMNS)
        for row in rows:
            data: dict[str, Any] = row.decision.model_dump(mode="json")
            why = data.get("why")
            writer.writerow(
                [
                    row.session,
                    row.participant,
                    row.visit,
                    round(row.t, 3),
                    *(_cell(data.get(key)) for key in DECISION_COLUMNS[4:-1]),
                    json.dumps(why, sort_keys=True) if why is not None else "",
                ]
            )


def plot_table4(path: Path, sessions: Sequence[SessionMetrics]) -> None:
    """Per metric, a panel with the paper's mean ± SD beside the simulation's."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 4, figsize=(13, 6))
    for ax, key in zip(axes.flat, METRICS, strict=True):
        values = [v for s in sessions if (v := session_value(s, key)) is not None]
        mean = statistics.fmean(values) if values else 0.0
        sd = statistics.pstdev(values) if len(values) > 1 else 0.0
        paper_mean, paper_sd = PAPER[key]
        ax.bar(
            ["paper", "simulated"],
            [paper_mean, mean],
            yerr=[paper_sd, sd],
            capsize=6,
            color=["#8c8c8c", "#3a75b0"],
        )
        ax.set_title(LABELS[key], fontsize=9)
        ax.tick_params(labelsize=8)
    fig.suptitle(f"Table 4: the paper's figures and the simulation's ({len(sessions)} sessions)")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def _interval(values: Sequence[float]) -> float:
    """Half the width of a normal 95 % interval of the mean of ``values``."""
    if len(values) < 2:
        return 0.0
    return 1.96 * statistics.stdev(values) / math.sqrt(len(values))


def plot_adaptation(path: Path, sessions: Sequence[SessionMetrics]) -> None:
    """Kendall's tau and robot-chosen cancels by visit: does the robot learn what each
    returning participant likes?"""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    repeat = max((s.visit for s in sessions), default=1)
    visits = list(range(1, repeat + 1))
    means = adaptation(sessions, repeat)
    tau_ci = [
        _interval([s.kendall_tau for s in sessions if s.visit == v and s.kendall_tau is not None])
        for v in visits
    ]
    cancel_ci = [
        _interval([float(s.robot_choice_cancels) for s in sessions if s.visit == v]) for v in visits
    ]
    people = len({s.participant for s in sessions})
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4))
    left.errorbar(visits, means["kendall_tau_by_session"], yerr=tau_ci, marker="o", capsize=4)
    left.axhline(0.7, color="#8c8c8c", linestyle="--", label="target 0.7 by visit 5")
    left.set_ylim(0.0, 1.0)
    left.set_xlabel("visit")
    left.set_ylabel("Kendall's tau, predicted vs true ranking")
    left.legend(loc="lower right", fontsize=8)
    right.errorbar(
        visits,
        means["robot_choice_cancels_by_session"],
        yerr=cancel_ci,
        marker="o",
        capsize=4,
        color="#b05a3a",
    )
    share = []
    for v in visits:
        rows = [s for s in sessions if s.visit == v]
        chosen = sum(s.robot_decisions for s in rows)
        share.append(sum(s.robot_choice_cancels for s in rows) / chosen if chosen else 0.0)
    right.plot(
        visits,
        share,
        marker="s",
        linestyle="--",
        color="#8c8c8c",
        label="per robot-chosen activity",
    )
    right.set_ylim(bottom=0.0)
    right.set_xlabel("visit")
    right.set_ylabel("cancels of robot-chosen activities / session")
    right.legend(loc="upper right", fontsize=8)
    for ax in (left, right):
        ax.set_xticks(visits)
        ax.grid(alpha=0.3)
    fig.suptitle(f"Adaptation: {people} participants, each coming {repeat} times (mean, 95 % CI)")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
