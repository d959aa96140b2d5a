"""The decision logic knows nothing of the study (calibrate inputs, never outputs).

No module under dms/, managers/, activities/, motivation/, memory/ or agenda/ imports
the simulator (but the composition root and the CLI tools, for the simulated robot), and
none names what only the study knows (the paper's figures, the
participants' pace, the robot's launch delay). The activities' content and behavior
files are data the study calibrates, so only Python source is scanned.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("dms", "managers", "activities", "motivation", "memory", "agenda")
STUDY_ONLY = (
    "paper_participant",
    "run_study",
    "study_settings",
    "PAPER_FAILURES",
    "LAUNCH_DELAY_S",
    "SURVEY_S",
    "menu_delay_s",
    "rating_delay_s",
    "launch_delay_s",
    "decline_menu_rate",
    "kendall_tau_by_session",
    "bored_below",
    "PARTICIPANT_INPUTS",
    "sim.calibration",
    "255.91",
    "43.12",
)


def _sources() -> list[Path]:
    files = [path for package in PACKAGES for path in (ROOT / package).rglob("*.py")]
    assert len(files) > 40
    return files


def test_no_decision_code_imports_the_simulator() -> None:
    offenders = []
    for path in _sources():
        tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
        for node in ast.walk(tree):
            names: list[str] = []
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            for name in names:
                if name == "sim" or name.startswith("sim."):
                    offenders.append(f"{path.relative_to(ROOT)}:{node.lineno}: {name}")
    # Only the composition root and the command-line tools may reach into sim/, and only
    # for the simulated robot, its CLIs and the visitor (and its persona): never the
    # study's modules.
    allowed_files = {"dms/cli.py"}
    allowed_modules = {"sim.cli", "sim.record_cli", "sim.robot", "sim.visitor", "sim.persona"}
    offenders = [
        o
        for o in offenders
        if not (o.split(":")[0] in allowed_files and o.split(": ")[-1] in allowed_modules)
    ]
    assert not offenders, offenders


def test_no_decision_code_names_study_parameters() -> None:
    offenders = [
        f"{path.relative_to(ROOT)}: {name}"
        for path in _sources()
        for name in STUDY_ONLY
        if name in path.read_text(encoding="utf-8")
    ]
    assert not offenders, offenders
