"""Raw data of a study or long-term run, for a researcher's own analysis (``--out DIR``).

- ``sessions.csv``: one row per session: who, which visit, the eight Table 4 metrics
  (empty where a session has none, e.g. no activity ended), the failures, the cancels of
  robot-chosen activities and Kendall's tau of the daemon's ranking after the session;
- ``decisions.csv``: every decision taken while a participant was there, with the
  session, the seconds since the participant sat down, and ``why`` (the decision's
  explanation as JSON, when the daemon gives one; empty otherwise);
- ``table4.png``: per metric, the paper's mean ± SD beside the simulation's.

Written when a run ends, so a researcher can rerun the numbers without rerunning the
simulation.
"""

from __future__ import annotations

import csv
import json
import statistics
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from sim.study import LABELS, METRICS, PAPER, DecisionRow, SessionMetrics, session_value

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
    """``sessions.csv``, ``decisions.csv`` and ``table4.png`` into ``out`` (created)."""
    out.mkdir(parents=True, exist_ok=True)
    paths = [out / "sessions.csv", out / "decisions.csv", out / "table4.png"]
    write_sessions(paths[0], sessions)
    write_decisions(paths[1], decisions)
    plot_table4(paths[2], sessions)
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
    fig.suptitle(f"Table 4: the seed's figures and the simulation's ({len(sessions)} sessions)")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
