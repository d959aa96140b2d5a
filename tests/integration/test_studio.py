"""``dms studio`` as a real process on 127.0.0.1, read as a script would (http.client).

The refusals (a foreign ``Host``, a missing or wrong token, a write from a foreign
``Origin``), and saving: every shipped behavior opened and saved unchanged is
byte-identical, an edit keeps the file's comments, a file changed on disk since it was
opened is not overwritten, and a behavior that does not load is only saved as a draft.
The page itself is driven in Chromium by test_studio_page.py.
"""

from __future__ import annotations

import hashlib
import http.client
import json
import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import pytest

from activities.library import BEHAVIORS_DIR
from tests.integration.viewer_harness import page_server


@dataclass(frozen=True)
class Studio:
    """A running studio: its page's URL (with the token), address and folder."""

    url: str
    host: str
    port: int
    token: str
    folder: Path

    def request(
        self,
        method: str,
        path: str,
        body: Any = None,
        headers: dict[str, str] | None = None,
        token: bool = True,
    ) -> tuple[int, Any]:
        connection = http.client.HTTPConnection(self.host, self.port, timeout=30)
        sent = dict(headers or {})
        if token:
            sent.setdefault("X-Studio-Token", self.token)
        data = None
        if body is not None:
            data = json.dumps(body).encode()
            sent["Content-Type"] = "application/json"
        try:
            connection.request(method, path, body=data, headers=sent)
            response = connection.getresponse()
            raw = response.read()
        finally:
            connection.close()
        try:
            return response.status, json.loads(raw)
        except ValueError:
            return response.status, raw.decode(errors="replace")


@contextmanager
def running_studio(folder: Path, extra: tuple[str, ...] = ()) -> Iterator[Studio]:
    """``dms studio --folder FOLDER --port 0 EXTRA...``; stopped with SIGINT, it must exit 0."""
    args = ["studio", "--folder", str(folder), "--port", "0", *extra]
    with page_server(args, "studio") as (url, _):
        parts = urlsplit(url)
        token = parts.query.removeprefix("token=")
        assert parts.hostname is not None and parts.port is not None
        yield Studio(url, parts.hostname, parts.port, token, folder)


def shipped_copy(tmp_path: Path) -> Path:
    folder = tmp_path / "behaviors"
    shutil.copytree(BEHAVIORS_DIR, folder)
    return folder


@pytest.fixture
def studio(tmp_path: Path) -> Iterator[Studio]:
    with running_studio(shipped_copy(tmp_path)) as running:
        yield running


@pytest.mark.integration
def test_a_foreign_host_a_missing_token_and_a_foreign_origin_are_refused(studio: Studio) -> None:
    status, text = studio.request("GET", "/api/behaviors", headers={"Host": "evil.example:80"})
    assert status == 421, text
    status, text = studio.request("GET", "/api/behaviors", token=False)
    assert status == 403 and "token" in text
    status, text = studio.request("GET", "/", token=False)
    assert status == 403 and "dms studio" in text
    status, _ = studio.request("GET", "/api/behaviors", headers={"X-Studio-Token": "wrong"})
    assert status == 403
    status, _ = studio.request("GET", f"/?token={studio.token}", token=False)
    assert status == 200
    # the cookie that visit set opens the page and its API without the token in the URL
    # (the viewer's link to the studio works once the studio's URL was opened)
    jar = {"Cookie": f"dms-studio-{studio.port}={studio.token}"}
    assert studio.request("GET", "/", headers=jar, token=False)[0] == 200
    assert studio.request("GET", "/api/behaviors", headers=jar, token=False)[0] == 200
    wrong = {"Cookie": f"dms-viewer-{studio.port}={studio.token}"}
    assert studio.request("GET", "/api/behaviors", headers=wrong, token=False)[0] == 403
    doc = {"name": "quiz", "outcomes": ["done"], "states": {}}
    origin = {"Origin": "http://evil.example"}
    status, text = studio.request("POST", "/api/save", {"doc": doc, "hash": None}, headers=origin)
    assert status == 403 and "origin" in text
    status, names = studio.request("GET", "/api/behaviors")
    assert status == 200 and "quiz" in names["names"]


@pytest.mark.integration
def test_every_shipped_behavior_saved_unchanged_is_byte_identical(studio: Studio) -> None:
    for path in sorted(studio.folder.glob("*.yaml")):
        before = path.read_bytes()
        status, opened = studio.request("GET", f"/api/behaviors/{path.stem}")
        assert status == 200, opened
        status, saved = studio.request(
            "POST", "/api/save", {"doc": opened["doc"], "hash": opened["hash"]}
        )
        assert status == 200 and saved["kind"] == "saved", saved
        assert path.read_bytes() == before, path.name


@pytest.mark.integration
def test_an_edit_keeps_the_comments_and_a_file_changed_on_disk_is_not_overwritten(
    studio: Studio,
) -> None:
    path = studio.folder / "sayings.yaml"
    text = path.read_text().replace("states:\n", "states:  # the sayings, in order\n", 1)
    path.write_text("# edited by hand\n" + text)
    _, opened = studio.request("GET", "/api/behaviors/sayings")
    doc = opened["doc"]
    doc["description"] = "Sayings, told one by one."
    status, saved = studio.request("POST", "/api/save", {"doc": doc, "hash": opened["hash"]})
    assert status == 200 and saved["kind"] == "saved", saved
    written = path.read_text()
    assert written.startswith("# edited by hand\n")
    assert "states:  # the sayings, in order\n" in written
    assert "Sayings, told one by one." in written
    path.write_text(written + "# changed by someone else\n")
    status, refused = studio.request("POST", "/api/save", {"doc": doc, "hash": saved["hash"]})
    assert status == 409 and "changed on disk" in refused["error"]
    assert path.read_text().endswith("# changed by someone else\n")


@pytest.mark.integration
def test_a_behavior_that_does_not_load_is_saved_only_as_a_draft(studio: Studio) -> None:
    path = studio.folder / "wait.yaml"
    before = path.read_bytes()
    _, opened = studio.request("GET", "/api/behaviors/wait")
    doc = opened["doc"]
    first = next(iter(doc["states"]))
    doc["states"][first]["transitions"] = {"done": "NOWHERE"}
    status, saved = studio.request("POST", "/api/save", {"doc": doc, "hash": opened["hash"]})
    assert status == 200 and saved["kind"] == "draft", saved
    assert any("NOWHERE" in message["text"] for message in saved["messages"])
    assert path.read_bytes() == before
    draft = studio.folder / "drafts" / "wait.draft.yaml"
    assert "NOWHERE" in draft.read_text()
    status, report = studio.request("POST", "/api/check", {"doc": doc})
    assert status == 200 and not report["ok"]
    assert report["messages"][0]["path"] == first
    assert report["messages"][0]["param"] == "transitions"


@pytest.mark.integration
def test_a_trial_steps_through_a_behavior_on_the_simulated_mini(studio: Studio) -> None:
    doc = {
        "name": "hello",
        "outcomes": ["done"],
        "states": {
            "HELLO": {"speak": {"text": "Hello!"}, "transitions": {"done": "NOD"}},
            "NOD": {"gesture": {"name": "nod"}, "transitions": {"done": "COUNT"}},
            "COUNT": {"set_data": {"add": {"greeted": 1}}, "transitions": {"done": "BYE"}},
            "BYE": {"speak": {"text": "Bye!"}},
        },
    }
    status, step = studio.request("POST", "/api/try/start", {"doc": doc})
    assert status == 200, step
    paths = [step["path"]]
    for _ in range(20):
        status, step = studio.request("POST", "/api/try/step")
        assert status == 200, step
        paths.append(step["path"])
        if step["finished"]:
            break
    assert step["finished"] and step["outcome"] == "done", step
    # a state that ends in the tick it starts (COUNT) is never seen running
    assert [path for path in paths if path] == ["HELLO", "NOD", "BYE"], paths
    assert step["robot"]["said"] == ["Hello!", "Bye!"], step
    assert step["userdata"] == {"greeted": 1}, step
    status, pose = studio.request("GET", "/api/robot")
    assert status == 200 and set(pose["joints"]) >= {"head", "neck", "hip"}


@pytest.mark.integration
def test_placements_are_kept_beside_the_file_and_bad_ones_are_refused(studio: Studio) -> None:
    path = studio.folder / "wait.yaml"
    before = path.read_bytes()
    _, opened = studio.request("GET", "/api/behaviors/wait")
    assert opened["layout"] == {"positions": {}} and opened["layout_note"] is None
    first = next(iter(opened["doc"]["states"]))
    for layout, wrong in [
        ({"positions": {first: [1, "far"]}}, f"{first!r}: [x, y], two finite numbers"),
        ({"positions": {first: [1e9, 0]}}, "two finite numbers"),
        ({"positions": []}, '{"positions": {"STATE/PATH": [x, y], ...}}'),
        ({"positions": {"": [0, 0]}}, "a state path of 1 to 400 characters"),
    ]:
        status, refused = studio.request(
            "POST", "/api/save", {"doc": opened["doc"], "hash": opened["hash"], "layout": layout}
        )
        assert status == 400 and wrong in refused["error"], refused
    assert not (studio.folder / "wait.layout.json").exists()
    layout = {"positions": {first: [120, -40.5]}}
    status, saved = studio.request(
        "POST", "/api/save", {"doc": opened["doc"], "hash": opened["hash"], "layout": layout}
    )
    assert status == 200 and saved["kind"] == "saved", saved
    assert path.read_bytes() == before
    _, again = studio.request("GET", "/api/behaviors/wait")
    assert again["layout"] == {"positions": {first: [120, -40.5]}}
    # a sidecar spoilt by hand is ignored, with its reason: the states are laid out anew
    (studio.folder / "wait.layout.json").write_text("{not json")
    status, spoilt = studio.request("GET", "/api/behaviors/wait")
    assert status == 200 and spoilt["layout"] == {"positions": {}}
    assert spoilt["layout_note"].startswith("wait.layout.json is not readable JSON")


@pytest.mark.integration
def test_the_simulated_mini_is_posed_by_hand_within_its_limits(studio: Studio) -> None:
    status, body = studio.request("GET", "/api/body")
    assert status == 200 and body["joints"]["head"] == {"low": -0.45, "high": 0.45, "neutral": 0}
    status, posed = studio.request("POST", "/api/robot/pose", {"joints": {"head": 2, "neck": 0.5}})
    assert status == 200 and posed["joints"]["head"] == 0.45 and posed["joints"]["neck"] == 0.5
    status, now = studio.request("GET", "/api/robot")
    assert status == 200 and now["joints"] == posed["joints"]
    for joints, wrong in [
        ({"tail": 1}, "no joint 'tail'"),
        ({"head": True}, "head: radians, a number"),
        ({"head": float("nan")}, "head: a finite number of radians"),
        ({}, "joints: {name: radians}"),
        ("up", "joints: {name: radians}"),
    ]:
        status, refused = studio.request("POST", "/api/robot/pose", {"joints": joints})
        assert status == 400 and wrong in refused["error"], refused
    status, compared = studio.request("POST", "/api/compare", {"doc": {"name": "Bad Name"}})
    assert status == 400 and "name" in compared["error"], compared
    (studio.folder / "broken.yaml").write_text("name: broken\nstates: [a, {b: \n  - c\n")
    status, compared = studio.request("POST", "/api/compare", {"doc": {"name": "broken"}})
    assert status == 422 and "broken.yaml: not readable YAML on disk" in compared["error"]
    assert "\n" not in compared["error"], compared
    broken = (studio.folder / "broken.yaml").read_bytes()
    doc = {"name": "broken", "outcomes": ["done"], "states": {"A": {"wait": {}}}}
    digest = hashlib.sha256(broken).hexdigest()
    status, refused = studio.request("POST", "/api/save", {"doc": doc, "hash": digest})
    assert status == 422 and "not readable YAML on disk" in refused["error"], refused
    assert (studio.folder / "broken.yaml").read_bytes() == broken


@pytest.mark.integration
def test_a_task_frame_stays_where_its_marker_was_last_seen_in_a_trial(studio: Studio) -> None:
    doc = {
        "name": "handle",
        "outcomes": ["done", "lost"],
        "frames": {"handle": {"of": "object:tag", "xyz": [0.0, 0.1, 0.2]}},
        "states": {
            "FIRST": {"look_at": {"frame": "handle"}, "transitions": {"done": "HOLD"}},
            "HOLD": {"wait": {"seconds": 2}, "transitions": {"done": "AGAIN"}},
            "AGAIN": {"point_at": {"frame": "handle"}},
        },
    }
    status, frames = studio.request("GET", "/api/frames")
    assert status == 200 and "object:tag" in frames["frames"]
    status, step = studio.request("POST", "/api/try/start", {"doc": doc})
    assert status == 200 and step["path"] == "FIRST", step
    (first,) = [c["args"] for c in step["commands"] if c["channel"] == "aim"]
    assert first["live"] is True and first["position"] == {"x": 0.5, "y": -0.1, "z": 0.2}
    status, hidden = studio.request("POST", "/api/try/marker", {"seen": False})
    assert status == 200 and hidden == {"seen": False}
    aims = []
    for _ in range(10):
        status, step = studio.request("POST", "/api/try/step")
        assert status == 200, step
        aims += [c["args"] for c in step["commands"] if c["channel"] == "aim"]
        if step["finished"]:
            break
    assert step["outcome"] == "done", step
    (again,) = aims
    assert again["live"] is False and again["position"] == first["position"]
    status, refused = studio.request("POST", "/api/try/marker", {"seen": "no"})
    assert status == 400 and "seen: true" in refused["error"]


@pytest.mark.integration
def test_a_name_with_a_line_break_or_too_long_is_a_one_line_400(studio: Studio) -> None:
    before = sorted(path.name for path in studio.folder.iterdir())
    tail = {"outcomes": ["done"], "states": {"HI": {"speak": {"text": "hi"}}}}
    for name in ("evil\n", "evil\r\n", "evil\nx", "x" * 5000, "", "Quiz"):
        status, refused = studio.request("POST", "/api/save", {"doc": {"name": name, **tail}})
        assert status == 400, (name[:10], refused)
        assert "name" in refused["error"] and "\n" not in refused["error"], refused
        assert len(refused["error"]) < 300, refused
    for path in ("evil%0A", "evil%0D%0A", "a" * 5000, "quiz%0A"):
        status, refused = studio.request("GET", f"/api/behaviors/{path}")
        assert status == 400, (path[:10], refused)
        assert "\n" not in refused["error"], refused
    status, text = studio.request("POST", "/api/try/start", {"doc": tail, "seed": "abc"})
    assert status == 400 and "seed" in text["error"], text
    assert sorted(path.name for path in studio.folder.iterdir()) == before
    status, names = studio.request("GET", "/api/behaviors")
    assert status == 200 and all("\n" not in name for name in names["names"])


@pytest.mark.integration
def test_a_behavior_that_is_not_yaml_is_refused_in_one_line(studio: Studio) -> None:
    (studio.folder / "broken.yaml").write_text("name: broken\nstates: [a, {b: \n  - c\n")
    status, refused = studio.request("GET", "/api/behaviors/broken")
    assert status == 422 and "not readable YAML" in refused["error"], refused
    assert "\n" not in refused["error"], refused


@pytest.mark.integration
def test_without_a_daemon_the_robot_is_not_posed_by_hand(studio: Studio) -> None:
    status, reply = studio.request("GET", "/api/robot/by-hand")
    assert status == 409 and "no daemon" in reply["error"], reply
    status, reply = studio.request("POST", "/api/robot/by-hand", {"on": True})
    assert status == 409 and "--connect" in reply["error"], reply
    status, reply = studio.request("POST", "/api/robot/by-hand", {"on": 1})
    assert status == 400 and "on: true or false" in reply["error"], reply
