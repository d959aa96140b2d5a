"""``--zenoh-config``: a deployment's own Zenoh file (TLS, access control) decides the endpoints."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from tests.integration.harness import client_session, free_port, wait_token

pytestmark = pytest.mark.integration


def _dms(*args: str, **kwargs: object) -> subprocess.Popen[str]:
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    return subprocess.Popen(  # type: ignore[call-overload, no-any-return]
        [sys.executable, "-m", "dms.cli", *args], env=env, text=True, **kwargs
    )


def test_the_files_listen_endpoints_stand_when_no_listen_flag_is_given(tmp_path: Path) -> None:
    port = free_port()
    zenoh_file = tmp_path / "zenoh.json5"
    zenoh_file.write_text(
        f'{{mode: "peer", listen: {{endpoints: ["tcp/127.0.0.1:{port}"]}},'
        " scouting: {multicast: {enabled: false}}}"
    )
    log = (tmp_path / "daemon.log").open("w")
    daemon = _dms(
        "run",
        "--zenoh-config",
        str(zenoh_file),
        "--db",
        str(tmp_path / "dms.db"),
        stdout=log,
        stderr=subprocess.STDOUT,
    )
    session = client_session(port)
    try:
        wait_token(session, "robots/mini/alive/dms")
        daemon.send_signal(signal.SIGTERM)
        assert daemon.wait(20) == 0
    finally:
        session.close()
        if daemon.poll() is None:
            daemon.kill()
        log.close()
    assert f"the endpoints of {zenoh_file}" in (tmp_path / "daemon.log").read_text()


def test_a_broken_zenoh_file_is_one_line(tmp_path: Path) -> None:
    zenoh_file = tmp_path / "zenoh.json5"
    zenoh_file.write_text("{mode: ")
    daemon = _dms(
        "run",
        "--zenoh-config",
        str(zenoh_file),
        "--db",
        str(tmp_path / "dms.db"),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    out, err = daemon.communicate(timeout=60)
    assert daemon.returncode == 1 and out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"dms: --zenoh-config {zenoh_file}")
