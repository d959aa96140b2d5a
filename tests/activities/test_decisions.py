"""Decide states against the rules: the outcome check, the ``[behaviors]`` folder, reloads.

A decide state's DMSL component may only activate outcomes the state declares (the
rules' verifier checks it). ``dms behavior check --rules`` refuses a mismatch; the daemon warns on
``dms/errors`` at load and on reload. Reloads keep the previous behaviors when a new
version is refused.
"""

from __future__ import annotations

import shutil
from functools import partial
from pathlib import Path

import pytest
from typer.testing import CliRunner

from activities import BehaviorLibrary, decision_problems, reload_rules_and_behaviors
from activities.cli import app
from activities.library import BEHAVIORS_DIR
from dms.cli import wire_simulated_robot
from dms.config import load_config
from dms.kernel.errors import ConfigError
from dms.rules import LiveRules, check_outcomes, rules_from_text
from sim.harness import Simulation

TALK = BEHAVIORS_DIR / "talk.yaml"
_CHOOSE_LINE = next(
    n for n, line in enumerate(TALK.read_text().splitlines(), 1) if line.strip() == "CHOOSE:"
)
TALK_CHOOSE = f"{TALK}:{_CHOOSE_LINE}: state TOPICS/TOPIC/CHOOSE:"
GOOD_TOPICS = 'component TalkTopic [ if params.user.age > 80 then activate "family" ]\n'
BAD_TOPICS = 'component TalkTopic [\n    activate "family"\n    activate "weather"\n]\n'

runner = CliRunner()
wire_simulated_robot()  # the composition root lets `behavior step|run` drive the simulated Mini


def test_an_activation_outside_the_outcomes_names_state_and_rule() -> None:
    spec = BehaviorLibrary.load().spec("talk")
    good = rules_from_text(GOOD_TOPICS, "topics.dmsl")
    assert decision_problems({"talk": spec}, partial(check_outcomes, good)) == []
    bad = rules_from_text(BAD_TOPICS, "topics.dmsl")
    assert decision_problems({"talk": spec}, partial(check_outcomes, bad)) == [
        f'{TALK_CHOOSE} topics.dmsl:3:5: activation "weather" of TalkTopic is not an outcome '
        'of the state (outcomes: "family", "food", "hobbies", "music")'
    ]


def test_a_component_the_rules_do_not_define_is_no_problem() -> None:
    rules = rules_from_text('component ChooseMode [ activate "hybrid" ]')
    assert BehaviorLibrary.load().check_decisions(partial(check_outcomes, rules)) == []


def test_behavior_check_with_rules_refuses_a_mismatch(tmp_path: Path) -> None:
    rules = tmp_path / "topics.dmsl"
    rules.write_text(GOOD_TOPICS)
    ok = runner.invoke(app, ["check", str(TALK), "--rules", str(rules)])
    assert ok.exit_code == 0 and ok.output == f"{TALK}: ok\n"
    rules.write_text(BAD_TOPICS)
    bad = runner.invoke(app, ["check", str(TALK), "--rules", str(rules)])
    assert bad.exit_code == 1
    assert bad.output.splitlines() == [
        f'{TALK_CHOOSE} {rules}:3:5: activation "weather" of TalkTopic is not an outcome '
        'of the state (outcomes: "family", "food", "hobbies", "music")'
    ]


def test_behavior_check_with_invalid_rules_prints_their_problems(tmp_path: Path) -> None:
    rules = tmp_path / "topics.dmsl"
    rules.write_text('component TalkTopic [ if nope then activate "family" ]\n')
    result = runner.invoke(app, ["check", str(TALK), "--rules", str(rules)])
    assert result.exit_code == 1
    assert result.output == f"{rules}:1:26: unknown name 'nope'\n"


def test_the_stack_warns_about_decide_states_at_load(tmp_path: Path) -> None:
    rules = tmp_path / "topics.dmsl"
    rules.write_text(BAD_TOPICS)
    config = tmp_path / "dms.toml"
    config.write_text('[rules]\nfiles = ["topics.dmsl"]\n')
    with Simulation(load_config(config), with_memory=False) as sim:
        assert [key for key, _line in sim.stack.warnings] == ["behaviors"]
        line = sim.stack.warnings[0][1]
        assert line.startswith(TALK_CHOOSE)
        assert '"weather" of TalkTopic' in line
        # a reload with matching rules: nothing to report any more
        rules.write_text(GOOD_TOPICS)
        sim.controller.reload_rules()
        assert sim.errors == []


def test_reload_keeps_the_previous_behaviors_and_reports_one_line(tmp_path: Path) -> None:
    folder = tmp_path / "behaviors"
    shutil.copytree(BEHAVIORS_DIR, folder)
    library = BehaviorLibrary.load(folder)
    before = library.spec("jokes")
    (folder / "jokes.yaml").write_text("name: jokes\noutcomes: [done]\nstates: {A: {nope: {}}}\n")
    (folder / "sleep.yaml").write_text("name: sleep\n")
    found = reload_rules_and_behaviors(library, None)
    assert len(found) == 1
    key, line = found[0]
    assert key == "behaviors" and "\n" not in line
    assert line.startswith(str(folder / "jokes.yaml")) and "more)" in line
    assert line.endswith("keeping the previous behaviors")
    assert library.spec("jokes") is before


def test_reload_reports_rules_problems_and_new_decision_mismatches(tmp_path: Path) -> None:
    rules_file = tmp_path / "topics.dmsl"
    rules_file.write_text(GOOD_TOPICS)
    rules = LiveRules([rules_file])
    library = BehaviorLibrary.load()
    rules_file.write_text("component TalkTopic [")
    found = reload_rules_and_behaviors(library, rules)
    assert [key for key, _ in found] == ["rules"] and "syntax error" in found[0][1]
    rules_file.write_text(BAD_TOPICS)
    found = reload_rules_and_behaviors(library, rules)
    assert [key for key, _ in found] == ["behaviors"] and TALK_CHOOSE in found[0][1]


def test_config_behaviors_folder_is_relative_to_the_file_and_must_exist(tmp_path: Path) -> None:
    (tmp_path / "mine").mkdir()
    config = tmp_path / "dms.toml"
    config.write_text('[behaviors]\nfolder = "mine"\n')
    assert load_config(config).behaviors.folder == tmp_path / "mine"
    assert load_config(None).behaviors.folder is None
    config.write_text('[behaviors]\nfolder = "missing"\n')
    with pytest.raises(ConfigError, match=r"behaviors.folder: .*missing is not a directory"):
        load_config(config)
    config.write_text('[behaviors]\nfolders = "mine"\n')
    with pytest.raises(ConfigError, match=r"behaviors.folders: Extra inputs"):
        load_config(config)


def test_an_invalid_behaviors_folder_is_a_one_line_config_error(tmp_path: Path) -> None:
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "jokes.yaml").write_text("name: other\n")
    config = tmp_path / "dms.toml"
    config.write_text('[behaviors]\nfolder = "mine"\n')
    with pytest.raises(ConfigError, match=r"^behaviors: .*jokes.yaml") as caught:
        Simulation(load_config(config), with_memory=False)
    assert "\n" not in str(caught.value)
