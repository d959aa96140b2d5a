"""``dms face`` against a real daemon, read and written as a script would: the token, the
Host and Origin guard, what each API call publishes on the bus, and what it refuses.

The helpers here (:func:`running_face`) also serve the browser's tests.
"""

from __future__ import annotations

import json
import subprocess
import sys
import threading
import urllib.error
import urllib.request
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from urllib.parse import parse_qs, urlsplit

import pytest
import zenoh

from tests.integration.harness import (
    READY_TIMEOUT_S,
    Collector,
    DaemonProcess,
    client_session,
    free_port,
)
from tests.integration.viewer_harness import EventStream, page_server

pytestmark = pytest.mark.integration

RULES = """
component ChooseMode [
    activate "user_choice"
]
component VoiceSettings [
    activate "rate:400"
]
"""
"""The person always chooses (a menu after each activity), and the activities speak fast:
a session of a few steps fits in a test."""


@dataclass
class Face:
    url: str
    """The page's URL with its token, as ``dms face`` printed it."""
    base: str
    token: str
    daemon: DaemonProcess
    session: zenoh.Session

    def call(
        self,
        path: str,
        body: bytes | dict[str, Any] | None = None,
        headers: dict[str, str] | None = None,
        token: bool = True,
    ) -> tuple[int, Any]:
        """One request to the face (POST when there is a body): its status and JSON."""
        query = ("&" if "?" in path else "?") + f"token={self.token}" if token else ""
        data = json.dumps(body).encode() if isinstance(body, dict) else body
        request = urllib.request.Request(
            f"{self.base}{path}{query}", data=data, headers=headers or {}
        )
        try:
            with urllib.request.urlopen(request, timeout=30) as response:
                text = response.read().decode()
                status = response.status
        except urllib.error.HTTPError as error:
            text, status = error.read().decode(), error.code
        try:
            return status, json.loads(text)
        except ValueError:
            return status, text


def daemon_config(tmp: Path, session_questions: int = 0, serve_profiles: bool = False) -> str:
    rules = tmp / "face.dmsl"
    rules.write_text(RULES)
    return (
        f"seed = 3\n[rules]\nfiles = [{json.dumps(str(rules))}]\n"
        '[inputs]\nstale_after_s = { "perception/user" = 30.0 }\n'
        f"[privacy]\nserve_profiles = {str(serve_profiles).lower()}\n"
        f"[controller]\nsession_questions = {session_questions}\nquestion_every = 0\n"
        "feedback_probability = 1.0\nnew_user_after_s = 0.0\n"
    )


@contextmanager
def running_face(
    tmp: Path, *face_args: str, session_questions: int = 0, serve_profiles: bool = False
) -> Iterator[Face]:
    """A daemon (its config: :func:`daemon_config`), a Zenoh session beside it, and ``dms
    face`` connected to it on a free port; the face must stop with exit 0."""
    daemon = DaemonProcess(tmp)
    daemon.config.write_text(daemon_config(tmp, session_questions, serve_profiles))
    session = client_session(daemon.port)
    try:
        daemon.start(session)
        args = ["face", "--connect", f"tcp/127.0.0.1:{daemon.port}", "--port", "0", *face_args]
        with page_server(args, "face", r"https?://\S+") as (url, _proc):
            parts = urlsplit(url)
            token = parse_qs(parts.query)["token"][0]
            yield Face(url, f"{parts.scheme}://{parts.netloc}", token, daemon, session)
    finally:
        daemon.kill()
        session.close()


@pytest.fixture(scope="module")
def face(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Face]:
    with running_face(tmp_path_factory.mktemp("face")) as running:
        yield running


def test_without_the_token_every_page_and_call_is_refused(face: Face) -> None:
    for path in ("/", "/events", "/api/snapshot"):
        status, text = face.call(path, token=False)
        assert status == 403 and "token" in text, (path, status, text)
    status, _ = face.call("/api/screen", {"choice": "yes"}, token=False)
    assert status == 403
    status, page = face.call("/")
    assert status == 200 and "face.js" in page
    status, _ = face.call("/static/face.js", token=False)
    assert status == 200  # the script holds nothing private


def test_a_foreign_host_or_origin_is_refused(face: Face) -> None:
    status, text = face.call("/api/snapshot", headers={"Host": "evil.example:80"})
    assert status == 421 and "host" in text
    status, text = face.call(
        "/api/screen", {"choice": "yes"}, headers={"Origin": "http://evil.example"}
    )
    assert status == 403 and "origin" in text
    screens = Collector(face.session, "robots/mini/perception/screen")
    status, body = face.call("/api/screen", {"choice": "yes"}, headers={"Origin": face.base})
    assert status == 200, body
    assert screens.wait_for(lambda m: True) == {"choice": "yes"}
    assert len(screens.messages) == 1  # the refused ones never reached the bus


def test_each_call_publishes_the_contracts_message(face: Face) -> None:
    speech = Collector(face.session, "robots/mini/perception/speech")
    touch = Collector(face.session, "robots/mini/perception/touch")
    users = Collector(face.session, "robots/mini/perception/user")
    assert face.call("/api/say", {"text": " my name is Ada "})[0] == 200
    assert speech.wait_for(lambda m: True) == {"text": "my name is Ada", "confidence": 1.0}
    assert face.call("/api/touch", {"part": "right_shoulder", "kind": "tap"})[0] == 200
    assert touch.wait_for(lambda m: True) == {"part": "right_shoulder", "kind": "tap"}

    status, body = face.call("/api/here", {"user_id": "ada"})
    assert status == 409 and "consent" in body["error"]
    decisions = Collector(face.session, "robots/mini/dms/decision")
    status, body = face.call("/api/here", {"user_id": "ada", "consent": True})
    assert status == 200, body
    users.wait_for(lambda m: m == {"present": True, "user_id": "ada", "ready": True})
    decisions.wait_for(lambda d: d["action"] == "start" and d["activity"] == "menu")
    status, body = face.call("/api/here", {"user_id": "ada"})  # she consented already
    assert status == 200, body
    assert face.call("/api/leave", {})[0] == 200
    users.wait_for(lambda m: m == {"present": False, "ready": False})
    decisions.wait_for(lambda d: d["reason"] == "user_left", timeout=30)
    mark = users.mark()
    users.wait_for(lambda m: m["present"] is False, start=mark)  # said again, as a camera does


@pytest.mark.parametrize(
    ("path", "body", "named"),
    [
        ("/api/screen", {"choice": ""}, "choice"),
        ("/api/screen", {"choice": "x" * 300}, "choice"),
        ("/api/touch", {"part": "elbow", "kind": "tap"}, "part"),
        ("/api/touch", {"part": "head", "kind": "kiss"}, "kind"),
        ("/api/say", {"text": 3}, "text"),
        ("/api/here", {"user_id": "a/b", "consent": True}, "user_id"),
        ("/api/here", {}, "user_id"),
        ("/api/screen", b"not json", "JSON"),
        ("/api/screen", b"[1, 2]", "object"),
        ("/api/voice", b"RIFF....not a wav", "WAV"),
    ],
)
def test_a_malformed_call_is_one_line_naming_what_is_wrong(
    face: Face, path: str, body: bytes | dict[str, Any], named: str
) -> None:
    status, reply = face.call(path, body)
    assert status == 400, reply
    assert named in reply["error"] and "\n" not in reply["error"], reply


def test_a_body_over_the_bound_is_refused(face: Face) -> None:
    status, reply = face.call("/api/say", b'{"text": "' + b"a" * 20_000 + b'"}')
    assert status == 413, reply
    assert face.call("/api/snapshot")[0] == 200  # and the face goes on


@pytest.mark.parametrize(
    ("args", "named"),
    [
        (["--robot", "BAD"], "--robot"),
        (["--language", "e!"], "--language"),
        (["--host", "10.1.2.3"], "--tls-cert"),
        (["--zenoh-config", "/nonexistent/face.json5"], "--zenoh-config"),
        (["--tls-cert", "/nonexistent/cert.pem"], "--tls-key"),
    ],
)
def test_a_bad_flag_is_one_line_before_anything_is_served(args: list[str], named: str) -> None:
    done = subprocess.run(
        [sys.executable, "-m", "dms.cli", "face", *args, "--port", "0"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 1, done
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("dms: ") and named in lines[0], done.stderr
    assert "face on" not in done.stderr


class FaceEvents(EventStream):
    """The face's ``/events`` (behind its token), read as :class:`EventStream` reads the
    viewer's."""

    def __init__(self, face: Face) -> None:
        self.events: list[tuple[str, Any]] = []
        self._cond = threading.Condition()
        url = f"{face.base}/events?token={face.token}"
        self._response = urllib.request.urlopen(url, timeout=READY_TIMEOUT_S)
        threading.Thread(target=self._read, daemon=True).start()


def test_on_a_secured_bus_the_face_role_brings_a_person_in(tmp_path: Path) -> None:
    """``dms secure init`` writes a ``face`` role: with its file, the face's perception
    reaches the daemon and the robot's commands and decisions reach the page."""
    from dms import secure
    from tests.integration.test_secure import SecuredDaemon, role_config

    directory = tmp_path / "sec"
    secure.init(directory, "mini", f"tls/127.0.0.1:{free_port()}")
    daemon = SecuredDaemon(tmp_path, directory / "dms.json5")
    admin = zenoh.open(role_config(directory, "admin"))
    try:
        daemon.start(admin)
        decisions = Collector(admin, "robots/mini/dms/decision")
        args = ["face", "--zenoh-config", str(directory / "face.json5"), "--port", "0"]
        with page_server(args, "face", r"https?://\S+") as (url, _proc):
            parts = urlsplit(url)
            token = parse_qs(parts.query)["token"][0]
            face = Face(url, f"{parts.scheme}://{parts.netloc}", token, daemon, admin)
            events = FaceEvents(face)
            try:
                events.wait_for("snapshot", lambda s: True)
                status, body = face.call("/api/here", {"user_id": "cleo", "consent": True})
                assert status == 200, body
                decisions.wait_for(lambda d: d["reason"] == "user_arrived", timeout=30)
                events.wait_for("decision", lambda d: d["reason"] == "user_arrived", timeout=30)
                events.wait_for("say", lambda d: bool(d["text"]), timeout=60)  # robot/command
                events.wait_for("state", lambda s: s["user"] == "cleo", timeout=30)
            finally:
                events.close()
    finally:
        daemon.kill()
        admin.close()
