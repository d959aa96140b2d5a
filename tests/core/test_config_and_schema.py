"""Configuration errors are one line naming the field; every message has a schema."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from dms.config import load_config
from dms.kernel.errors import ConfigError
from dms.kernel.messages import SCHEMAS, write_schemas
from motivation import DEFAULT_DRIVES
from motivation import load_config as load_motivation


def test_defaults_match_the_contract() -> None:
    settings = load_config(None)
    assert settings.robot_id == "mini"
    assert settings.zenoh.listen == ["tcp/127.0.0.1:7447"]
    assert settings.robot == "sim"


def test_flags_override_the_file(tmp_path: Path) -> None:
    path = tmp_path / "dms.toml"
    path.write_text('robot_id = "alpha"\n[zenoh]\nlisten = ["tcp/127.0.0.1:9000"]\n')
    settings = load_config(path, robot_id="beta", listen=["tcp/127.0.0.1:9001"])
    assert settings.robot_id == "beta"
    assert settings.zenoh.listen == ["tcp/127.0.0.1:9001"]


@pytest.mark.parametrize(
    ("text", "fragment"),
    [
        ('robot_id = "Not OK"', "robot_id"),
        ('robot_id = "mini\\n"', "robot_id"),
        ("[controller]\nfeedback_probability = 2", "controller.feedback_probability"),
        ("[controller]\nunknown = 1", "controller.unknown"),
        ('[inputs]\nstale_after_s = {"perception/nose" = 1.0}', "perception/nose"),
        ("robot_id = ", "not valid TOML"),
        ('robot = "hologram"', "robot"),
    ],
)
def test_bad_config_is_one_line_naming_the_field(tmp_path: Path, text: str, fragment: str) -> None:
    path = tmp_path / "dms.toml"
    path.write_text(text)
    with pytest.raises(ConfigError) as caught:
        load_config(path)
    message = str(caught.value)
    assert fragment in message and str(path) in message and "\n" not in message


def test_missing_config_file_is_reported(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="cannot read"):
        load_config(tmp_path / "nope.toml")


def test_every_message_gets_a_json_schema(tmp_path: Path) -> None:
    paths = write_schemas(tmp_path)
    assert len(paths) == len(SCHEMAS)
    state = json.loads((tmp_path / "dms_state.schema.json").read_text())
    assert {
        "robot",
        "tick",
        "time",
        "mode",
        "activity",
        "suspended",
        "motivation",
        "inputs",
    } <= set(state["properties"])
    params = json.loads((tmp_path / "params.schema.json").read_text())
    assert params["type"] == "object"


def test_the_readme_configuration_is_valid(tmp_path: Path) -> None:
    readme = (Path(__file__).resolve().parents[2] / "README.md").read_text()
    found = re.search(r"```toml\n(.*?)```", readme, re.S)
    assert found, "README has no TOML example"
    path = tmp_path / "dms.toml"
    path.write_text(found.group(1))
    settings = load_config(path)
    assert settings.timezone == "Europe/Madrid" and settings.controller.done_timeout_s == 120
    motivation = load_motivation(settings.motivation)
    assert motivation.drives["rest"].threshold == 65
    assert motivation.drives["rest"].rate_per_hour == DEFAULT_DRIVES["rest"]["rate_per_hour"]
