"""``dms behavior``: check, show, step (scripted stdin), run, schema."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from typer.testing import CliRunner

from activities import BehaviorError
from activities.cli import app
from activities.library import BEHAVIORS_DIR
from activities.schema import SCHEMA_PATH
from dms.cli import wire_simulated_robot

runner = CliRunner()
wire_simulated_robot()  # the composition root lets `behavior step|run` drive the simulated Mini
QUIZ = str(BEHAVIORS_DIR / "quiz.yaml")


def test_check_accepts_good_files_and_names_bad_ones(tmp_path: Path) -> None:
    good = runner.invoke(app, ["check", QUIZ, str(BEHAVIORS_DIR / "dance.yaml")])
    assert good.exit_code == 0
    assert good.output.count(": ok") == 2
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: bad\noutcomes: [done]\nstates:\n  A:\n    speak: {text: 3.5, loud: 1}\n")
    result = runner.invoke(app, ["check", QUIZ, str(bad)])
    assert result.exit_code == 1
    lines = result.output.strip().splitlines()
    assert lines[0].endswith("quiz.yaml: ok")
    assert lines[1] == f"{bad}:5: state A: speak: parameter 'text' must be string, not float 3.5"
    assert lines[2].startswith(f"{bad}:5: state A: speak: unknown parameter 'loud'")


def test_show_draws_dot_and_mermaid_with_clusters() -> None:
    dot = runner.invoke(app, ["show", QUIZ, "--format", "dot", "--active", "GAME/ROUNDS"])
    assert dot.exit_code == 0
    assert dot.output.startswith('digraph "quiz"')
    assert "subgraph cluster_s_GAME {" in dot.output
    assert "subgraph cluster_s_GAME_ROUNDS_ROUND {" in dot.output
    assert 's_INTRO -> s_PICK [label="done"' in dot.output
    assert 'fillcolor="#fff8e1"' in dot.output  # the active cluster is highlighted
    mermaid = runner.invoke(app, ["show", QUIZ, "--format", "mermaid"])
    assert mermaid.exit_code == 0
    assert mermaid.output.startswith("stateDiagram-v2")
    assert 'state "GAME [guard]" as s_GAME {' in mermaid.output
    assert "s_GAME --> s_RESULT : touched" in mermaid.output


def test_show_refuses_a_bad_file(tmp_path: Path) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: bad\noutcomes: [done]\nstates:\n  A:\n    dance_wildly: {}\n")
    result = runner.invoke(app, ["show", str(bad)])
    assert isinstance(result.exception, BehaviorError)
    assert "bad.yaml:5: state A: unknown block 'dance_wildly'" in str(result.exception)


def test_step_goes_one_state_per_enter_and_takes_answers(tmp_path: Path) -> None:
    colour = tmp_path / "colour.yaml"
    colour.write_text(
        "name: colour\noutcomes: [done]\nstates:\n"
        "  HELLO:\n    speak: {text: 'Hello {user.name}'}\n    transitions: {done: ASK}\n"
        "  ASK:\n    ask: {question: 'Red or blue?', choices: [red, blue]}\n"
        "    transitions: {answered: SAY, no_answer: done}\n"
        "  SAY:\n    speak: {text: 'You said {answer}'}\n"
    )
    result = runner.invoke(app, ["step", str(colour), "--user", "ana"], input="\nblue\n\n")
    assert result.exit_code == 0, result.output
    lines = [line.removeprefix("> ") for line in result.output.splitlines()]
    states = [line.split()[-1] for line in lines if line.startswith("[")]
    assert states == ["HELLO", "ASK", "SAY", "-"]
    assert 'robot: cmd-1 speech.say {"text": "Hello Ana"}' in result.output
    assert "event taken" in result.output
    assert 'userdata.answer = "blue"' in result.output  # what changed is printed
    assert "You said blue" in result.output
    assert result.output.strip().endswith("completed: done")


def test_step_waits_at_a_question_and_prints_only_what_changed() -> None:
    """A second Enter does not run through the question's timeout, and a
    step prints the userdata keys that changed (a long value cut), not all of it."""
    result = runner.invoke(app, ["step", QUIZ, "--user", "ana"], input="\n\n\nParis\n6\nq\n")
    assert result.exit_code == 0, result.output
    out = result.output
    assert out.count("waiting for an answer") == 2, out
    assert "Sorry, I did not get that" in out, "a wrong answer: asked again, and waits"
    assert "Correct! The answer is 6." in out
    assert "MISSED" not in out, "no timeout went by"
    assert out.count("userdata.score = 0") == 1
    questions = next(line for line in out.splitlines() if "userdata.questions =" in line)
    assert len(questions) < 160 and "characters)" in questions
    assert out.count("userdata.questions") == 1, "an unchanged value is not printed again"


def test_step_skip_lets_the_question_time_out() -> None:
    result = runner.invoke(app, ["step", QUIZ], input="\nskip\nq\n")
    assert result.exit_code == 0, result.output
    asked = [line for line in result.output.splitlines() if "speech.say" in line]
    assert sum("Question 1." in line for line in asked) == 2, "timed out, then asked again"
    assert "waiting for an answer" not in result.output


@pytest.mark.skipif(
    shutil.which("dot") is None, reason="Graphviz's dot is not installed (.ci/run installs it)"
)
def test_show_draws_svg_and_png_with_graphviz(tmp_path: Path) -> None:
    svg = runner.invoke(app, ["show", QUIZ, "--format", "svg"])
    assert svg.exit_code == 0, svg.output
    assert "<svg" in svg.output and "INTRO" in svg.output
    png = tmp_path / "quiz.png"
    done = runner.invoke(app, ["show", QUIZ, "--format", "png", "--output", str(png)])
    assert done.exit_code == 0, done.output
    assert png.read_bytes().startswith(b"\x89PNG\r\n")


def test_show_svg_without_graphviz_is_one_line(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("PATH", "/nonexistent")
    result = runner.invoke(app, ["show", QUIZ, "--format", "svg"])
    assert result.exit_code == 1
    assert result.output.strip().splitlines() == [
        "dms: --format svg needs Graphviz's dot on PATH (apt-get install graphviz); "
        "--format dot or mermaid need nothing"
    ]


def test_step_can_be_stopped() -> None:
    result = runner.invoke(app, ["step", QUIZ], input="\nq\n")
    assert result.exit_code == 0
    assert result.output.strip().endswith("cancelled: cancelled")


def test_step_runs_on_at_the_end_of_input() -> None:
    result = runner.invoke(app, ["step", str(BEHAVIORS_DIR / "jokes.yaml")], input="\n")
    assert result.exit_code == 0
    assert result.output.strip().endswith("completed: done")
    assert result.output.count("speech.say") == 2 + 20 * 2  # intro, 20 jokes, end


def test_run_answers_and_reports_json() -> None:
    result = runner.invoke(
        app, ["run", str(BEHAVIORS_DIR / "menu.yaml"), "--answer", "let's do the quiz", "--json"]
    )
    assert result.exit_code == 0
    summary = json.loads(result.output)
    assert summary["status"] == "completed"
    assert summary["redirect"] == "quiz"
    notification = runner.invoke(
        app, ["run", str(BEHAVIORS_DIR / "notification.yaml"), "--text", "Lunch time."]
    )
    assert "Lunch time." in notification.output
    assert notification.output.strip().splitlines()[-1].startswith("completed: done after")


@pytest.mark.parametrize("name", ["sleep", "wait"])
def test_run_cancels_endless_behaviors_after_max_s(name: str) -> None:
    result = runner.invoke(
        app, ["run", str(BEHAVIORS_DIR / f"{name}.yaml"), "--max-s", "60", "--json"]
    )
    summary = json.loads(result.output)
    assert summary["status"] == "cancelled"
    assert 60 <= summary["seconds"] <= 61


def test_schema_prints_the_published_schema() -> None:
    result = runner.invoke(app, ["schema"])
    assert result.exit_code == 0
    assert json.loads(result.output) == json.loads(SCHEMA_PATH.read_text())
