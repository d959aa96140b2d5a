"""The README's TOML example, copied as a reader would copy it, runs the daemon.

The block under "### Configuration (TOML)" is written to a file as it stands and given
to the real ``dms run --config``. Only what must differ on a shared test machine is
moved, through the documented precedence and never in the file: the listening port (a
flag, over the file) and the user's data folder, where the default database goes
(``XDG_DATA_HOME``).
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from dms.config import load_config
from tests.integration.harness import Collector, client_session, free_port, wait_token

pytestmark = pytest.mark.integration

README = Path(__file__).resolve().parents[2] / "README.md"
_SCRIPT = Path(sys.executable).with_name("dms")
DMS = [str(_SCRIPT)] if _SCRIPT.exists() else [sys.executable, "-m", "dms.cli"]


def readme_toml() -> str:
    text = README.read_text(encoding="utf-8")
    section = text.split("### Configuration (TOML)", 1)[1]
    found = re.search(r"```toml\n(.*?)```", section, re.DOTALL)
    assert found, "no TOML example under '### Configuration (TOML)' in README.md"
    return found.group(1)


def test_the_readme_toml_loads(tmp_path: Path) -> None:
    path = tmp_path / "dms.toml"
    path.write_text(readme_toml(), encoding="utf-8")
    settings = load_config(path, use_environment=False)
    assert settings.robot_id == "mini" and settings.seed == 7
    for rules in settings.rules.files:
        assert rules.is_file(), f"the example names {rules}, which a copy does not have"


def test_the_readme_toml_runs_as_written(tmp_path: Path) -> None:
    path = tmp_path / "dms.toml"
    path.write_text(readme_toml(), encoding="utf-8")
    port = free_port()
    clean = {k: v for k, v in os.environ.items() if not k.startswith("DMS_")}
    env = {**clean, "XDG_DATA_HOME": str(tmp_path / "data"), "PYTHONUNBUFFERED": "1"}
    session = client_session(port)
    log = (tmp_path / "daemon.log").open("w")
    process = subprocess.Popen(
        [*DMS, "run", "--config", str(path), "--listen", f"tcp/127.0.0.1:{port}", "--quiet"],
        cwd=tmp_path,
        stdout=log,
        stderr=subprocess.STDOUT,
        text=True,
        env=env,
    )
    try:
        states = Collector(session, "robots/mini/dms/state")
        wait_token(session, "robots/mini/alive/dms")
        state = states.wait_for(lambda s: s["tick"] >= 2)  # the loop runs
        assert state["robot"] == "mini"
        process.send_signal(signal.SIGTERM)
        assert process.wait(30) == 0, (tmp_path / "daemon.log").read_text()
    finally:
        if process.poll() is None:
            process.kill()
            process.wait(10)
        log.close()
        session.close()
    assert (tmp_path / "data" / "dms" / "dms.db").exists()  # the default database
    lines = (tmp_path / "daemon.log").read_text().splitlines()
    # log_level = "info", log_format = "text": the ready line, as text.
    assert any(" INFO dms.daemon: robot mini ready on " in line for line in lines), lines
