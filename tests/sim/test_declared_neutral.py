"""Declaring activities is a change only where one is declared: a behaviors folder that
declares none gives a seeded session the very decisions of the shipped behaviors, and
one that declares an activity puts it among the robot's choices (and takes it out again
for the next simulation, which builds its own catalogue)."""

from __future__ import annotations

import shutil
from pathlib import Path

import yaml

from activities.library import BEHAVIORS_DIR
from dms.kernel.activity_names import current
from sim.runner import run_scenario
from sim.scenario import SCENARIO_DIR

DECLARED = """\
name: song_or_chat
activity: {manager: entertainment, menu: Song or chat, features: {hobbies: [music]}}
outcomes: [done]
states:
  SING:
    speak: {text: "La la la, a little song for you."}
    transitions: {done: done}
"""


def _scenario_on(
    folder: Path | None, tmp: Path, name: str, shipped: str = "visitor_session"
) -> Path:
    """The ``shipped`` scenario, on ``folder``'s behaviors (None: the shipped ones, as
    written)."""
    data = yaml.safe_load((SCENARIO_DIR / f"{shipped}.yaml").read_text())
    if folder is not None:
        data["settings"] = {**data.get("settings", {}), "behaviors": {"folder": str(folder)}}
    path = tmp / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return path


def _decisions(path: Path) -> list[dict[str, object]]:
    result = run_scenario(path)
    return [{"t": d.t, **d.decision.model_dump(mode="json")} for d in result.decisions]


def test_a_folder_that_declares_nothing_decides_as_the_shipped_behaviors(tmp_path: Path) -> None:
    folder = tmp_path / "behaviors"
    shutil.copytree(BEHAVIORS_DIR, folder)
    shipped = _decisions(_scenario_on(None, tmp_path, "shipped"))
    copied = _decisions(_scenario_on(folder, tmp_path, "copied"))
    assert copied == shipped
    assert len(shipped) > 10  # a whole session, not an empty one


def test_a_declared_activity_is_among_the_choices_only_while_its_folder_runs(
    tmp_path: Path,
) -> None:
    folder = tmp_path / "behaviors"
    shutil.copytree(BEHAVIORS_DIR, folder)
    (folder / "song_or_chat.yaml").write_text(DECLARED, encoding="utf-8")
    # the robot chooses for a user who leaves the choice to it
    declared = _decisions(_scenario_on(folder, tmp_path, "declared", "mode_autonomous"))
    assert "song_or_chat" in current().entertainment
    chosen = [d for d in declared if d["reason"] == "preference" and d["why"]["choice"]]
    assert chosen, "the robot chose nothing itself"
    assert all("song_or_chat" in d["why"]["choice"]["candidates"] for d in chosen)
    _decisions(_scenario_on(None, tmp_path, "after"))
    assert "song_or_chat" not in current().managers
