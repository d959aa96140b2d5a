"""docs/configuration.md names every setting's variable, and deploy/ holds a unit and a
configuration that systemd and ``dms run`` accept."""

from __future__ import annotations

import configparser
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from pydantic import BaseModel

from dms.config import Settings, env_name, load_config

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "configuration.md"
UNIT = ROOT / "deploy" / "dms.service"


def _variables() -> list[str]:
    names = []
    for name, field in Settings.model_fields.items():
        if field.exclude:
            continue
        section = field.annotation
        if isinstance(section, type) and issubclass(section, BaseModel):
            names += [env_name([name, inner]) for inner in section.model_fields]
        else:
            names.append(env_name([name]))
    return names


def test_every_setting_has_its_variable_in_the_doc() -> None:
    text = DOC.read_text(encoding="utf-8")
    missing = [name for name in _variables() if f"`{name}`" not in text]
    assert not missing, f"docs/configuration.md does not name {missing}"


def _unit() -> configparser.RawConfigParser:
    parser = configparser.RawConfigParser(strict=False, interpolation=None)
    parser.optionxform = str  # type: ignore[assignment,method-assign]
    parser.read_string(UNIT.read_text(encoding="utf-8"))
    return parser


def test_the_unit_is_a_notify_service_with_a_watchdog_and_restarts() -> None:
    service = _unit()["Service"]
    assert service["Type"] == "notify" and service["NotifyAccess"] == "main"
    assert service["Restart"] == "on-failure" and int(service["WatchdogSec"]) > 0
    assert service["ExecReload"] == "/bin/kill -HUP $MAINPID"
    command = shlex.split(service["ExecStart"])
    assert command[1] == "run"
    config = Path(command[command.index("--config") + 1])
    assert config == Path("/etc/dms/dms.toml")
    settings = load_config(ROOT / "deploy" / "dms.toml", use_environment=False)
    assert settings.db == "sqlite:////var/lib/dms/dms.db"  # the unit's StateDirectory
    assert _unit()["Service"]["StateDirectory"] == "dms"


def test_systemd_accepts_the_unit(tmp_path: Path) -> None:
    analyze = shutil.which("systemd-analyze")
    if analyze is None:
        pytest.skip("systemd-analyze is not installed")
    dms = Path(sys.executable).with_name("dms")
    unit = tmp_path / "dms.service"  # the same unit, run from this checkout's dms
    unit.write_text(UNIT.read_text().replace("/opt/dms/bin/dms", str(dms)))
    result = subprocess.run(
        [analyze, "verify", str(unit)], capture_output=True, text=True, timeout=60
    )
    assert result.returncode == 0, result.stderr
    assert "dms.service" not in result.stderr, result.stderr  # no warning about it
