"""Configuration errors are one line naming the field; every message has a schema."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from dms.config import load_config
from dms.errors import ConfigError
from dms.messages import SCHEMAS, write_schemas


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
