"""``dms studio`` and ``dms view`` over HTTPS, as real processes on 127.0.0.1.

A ``--host`` beyond loopback without TLS files is refused before anything binds; with
``--tls-cert`` and ``--tls-key`` (here those ``dms secure init`` writes, trusted through
its ``ca.pem``) the pages answer over HTTPS only, the studio still asking for its token;
a missing or wrong file is one line. No test binds any address but 127.0.0.1.
"""

from __future__ import annotations

import http.client
import json
import shutil
import socket
import ssl
import subprocess
import sys
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import pytest

from activities.library import BEHAVIORS_DIR
from dms.secure import init as secure_init
from dms.viewer.tls import server_context
from tests.integration.viewer_harness import page_server

HTTPS_URL = r"https://\S+"


@pytest.fixture(scope="module")
def certs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder from ``dms secure init``: ``ca.pem`` and role certificates naming
    127.0.0.1 and localhost."""
    directory = tmp_path_factory.mktemp("secure")
    secure_init(directory, "mini")
    return directory


def client_context(certs: Path) -> ssl.SSLContext:
    """What a browser that imported the deployment's CA would trust."""
    return ssl.create_default_context(cafile=str(certs / "ca.pem"))


def run_dms(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "dms.cli", *args], capture_output=True, text=True, timeout=60
    )


def said_one_line(done: subprocess.CompletedProcess[str], expected: str) -> None:
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    assert done.returncode != 0, done.stderr
    assert len(lines) == 1 and expected in lines[0], done.stderr


def isolated_zenoh(tmp_path: Path) -> Path:
    """A Zenoh config that reaches no one: the viewer starts without a daemon."""
    path = tmp_path / "alone.json5"
    path.write_text(
        json.dumps(
            {
                "mode": "peer",
                "connect": {"endpoints": []},
                "listen": {"endpoints": []},
                "scouting": {"multicast": {"enabled": False}},
            }
        )
    )
    return path


def https_get(
    url: str, path: str, context: ssl.SSLContext, headers: dict[str, str] | None = None
) -> tuple[int, Any]:
    parts = urlsplit(url)
    assert parts.hostname is not None and parts.port is not None
    connection = http.client.HTTPSConnection(
        parts.hostname, parts.port, timeout=30, context=context
    )
    try:
        connection.request("GET", path, headers=headers or {})
        response = connection.getresponse()
        raw = response.read()
    finally:
        connection.close()
    try:
        return response.status, json.loads(raw)
    except ValueError:
        return response.status, raw.decode(errors="replace")


def plain_http_fails(url: str) -> bool:
    parts = urlsplit(url)
    assert parts.hostname is not None and parts.port is not None
    connection = http.client.HTTPConnection(parts.hostname, parts.port, timeout=30)
    try:
        connection.request("GET", "/")
        connection.getresponse().read()
    except (http.client.HTTPException, OSError):
        return True
    finally:
        connection.close()
    return False


@pytest.mark.integration
@pytest.mark.parametrize("command", ["studio", "view"])
def test_a_host_beyond_loopback_without_tls_is_refused_before_binding(
    command: str, tmp_path: Path
) -> None:
    # A listener of ours on 127.0.0.1:PORT makes binding 0.0.0.0:PORT fail: had the
    # command bound first, it would say "cannot serve" instead.
    with socket.socket() as held:
        held.bind(("127.0.0.1", 0))
        held.listen(1)
        port = str(held.getsockname()[1])
        extra = ["--folder", str(tmp_path)] if command == "studio" else []
        done = run_dms(command, *extra, "--host", "0.0.0.0", "--port", port)
    said_one_line(done, "--host 0.0.0.0 serves the")
    assert "--tls-cert" in done.stderr and "dms secure init" in done.stderr
    assert "keep the default --host 127.0.0.1" in done.stderr


@pytest.mark.integration
def test_the_studio_serves_https_with_its_token(certs: Path, tmp_path: Path) -> None:
    folder = tmp_path / "behaviors"
    shutil.copytree(BEHAVIORS_DIR, folder)
    tls = ["--tls-cert", str(certs / "admin.pem"), "--tls-key", str(certs / "admin.key")]
    args = ["studio", "--folder", str(folder), "--port", "0", *tls]
    with page_server(args, "studio", HTTPS_URL) as (url, _proc):
        token = urlsplit(url).query.removeprefix("token=")
        context = client_context(certs)
        status, names = https_get(url, "/api/behaviors", context, {"X-Studio-Token": token})
        assert status == 200 and names["names"], names
        status, text = https_get(url, "/api/behaviors", context)
        assert status == 403 and "token" in text
        status, _ = https_get(url, f"/?token={token}", context)
        assert status == 200
        assert plain_http_fails(url)
        # A write from the page itself carries an https Origin: it is the page's own.
        parts = urlsplit(url)
        connection = http.client.HTTPSConnection(
            str(parts.hostname), parts.port, timeout=30, context=context
        )
        try:
            doc = {"name": "quiz", "outcomes": ["done"], "states": {}}
            connection.request(
                "POST",
                "/api/check",
                body=json.dumps({"doc": doc}),
                headers={
                    "X-Studio-Token": token,
                    "Origin": f"https://{parts.netloc}",
                    "Content-Type": "application/json",
                },
            )
            assert connection.getresponse().status == 200
        finally:
            connection.close()


@pytest.mark.integration
def test_the_viewer_serves_its_snapshot_over_https(certs: Path, tmp_path: Path) -> None:
    tls = ["--tls-cert", str(certs / "app.pem"), "--tls-key", str(certs / "app.key")]
    args = ["view", "--zenoh-config", str(isolated_zenoh(tmp_path)), "--port", "0", *tls]
    with page_server(args, "viewer", HTTPS_URL) as (url, _proc):
        context = client_context(certs)
        status, text = https_get(url, "/api/snapshot", context)
        assert status == 403 and "dms view" in text, text
        token = urlsplit(url).query.removeprefix("token=")
        status, snapshot = https_get(url, "/api/snapshot", context, {"X-Viewer-Token": token})
        assert status == 200 and "robots" in snapshot, snapshot
        assert https_cookie(url, f"/?token={token}", context).endswith("; Secure")
        assert plain_http_fails(url)


def https_cookie(url: str, path: str, context: ssl.SSLContext) -> str:
    """The cookie a page over HTTPS sets on a visit to ``path``."""
    parts = urlsplit(url)
    connection = http.client.HTTPSConnection(
        str(parts.hostname), parts.port, timeout=30, context=context
    )
    try:
        connection.request("GET", path)
        response = connection.getresponse()
        response.read()
        assert response.status == 200, response.status
        return str(response.headers["Set-Cookie"])
    finally:
        connection.close()


@pytest.mark.integration
def test_a_missing_or_wrong_tls_file_is_one_line(certs: Path, tmp_path: Path) -> None:
    garbage = tmp_path / "garbage.key"
    garbage.write_text("not a key\n")
    cert = str(certs / "admin.pem")
    cases = [
        (["--tls-cert", cert, "--tls-key", str(tmp_path / "missing.key")], "missing.key"),
        (["--tls-cert", cert, "--tls-key", str(garbage)], "not a PEM private key"),
        (["--tls-cert", cert, "--tls-key", str(certs / "app.key")], "is not the key of"),
        (["--tls-cert", cert], "go together"),
    ]
    for extra, expected in cases:
        said_one_line(run_dms("studio", "--folder", str(tmp_path), "--port", "0", *extra), expected)
    view = ["view", "--port", "0", "--tls-cert", str(garbage), "--tls-key", str(garbage)]
    said_one_line(run_dms(*view), "not a PEM certificate")


def test_the_pages_take_tls_1_2_at_least(certs: Path) -> None:
    context = server_context(certs / "dms.pem", certs / "dms.key")
    assert context is not None and context.minimum_version == ssl.TLSVersion.TLSv1_2
    assert server_context(None, None) is None
