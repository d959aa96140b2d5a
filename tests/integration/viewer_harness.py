"""``dms view`` as a process, read as a script or a browser would: the helpers of the
viewer's tests."""

from __future__ import annotations

import json
import os
import queue
import re
import signal
import subprocess
import sys
import threading
import urllib.parse
import urllib.request
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from tests.integration.harness import READY_TIMEOUT_S

CHROMIUM = Path("/usr/bin/chromium")
CHROMIUM_ARGS = ["--no-sandbox", "--disable-dev-shm-usage"]


@contextmanager
def running_viewer(port: int | None, *extra: str) -> Iterator[str]:
    """``dms view --connect`` the daemon (on ``port``; None: ``extra`` says where) on a free
    HTTP port; yields the page's URL once the viewer says it serves. Stopped with SIGINT,
    it must exit 0."""
    with viewer_process(port, *extra) as (url, _proc):
        yield url


@contextmanager
def viewer_process(port: int | None, *extra: str) -> Iterator[tuple[str, subprocess.Popen[str]]]:
    """:func:`running_viewer`, yielding its process too (to measure it)."""
    connect = ["--connect", f"tcp/127.0.0.1:{port}"] if port is not None else []
    with page_server(["view", *connect, "--port", "0", *extra], "viewer") as (url, proc):
        yield url, proc


def at(url: str, path: str) -> str:
    """``path`` (``events``, ``api/snapshot``) of the page printed as ``url``
    (``http://HOST:PORT/?token=...``), carrying its token as a script would."""
    parts = urllib.parse.urlsplit(url)
    return urllib.parse.urlunsplit((parts.scheme, parts.netloc, f"/{path}", parts.query, ""))


def token_of(url: str) -> str:
    """The token a page's printed URL carries."""
    return urllib.parse.parse_qs(urllib.parse.urlsplit(url).query)["token"][0]


@contextmanager
def page_server(
    args: list[str], name: str, url_pattern: str = r"http://\S+"
) -> Iterator[tuple[str, subprocess.Popen[str]]]:
    """``dms ARGS...`` serving a page (the viewer, the studio): yields the URL its
    ``dms: NAME on URL`` line gives, and the process. Stopped with SIGINT, it must exit
    0 without a traceback."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "dms.cli", *args],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        env=dict(os.environ, PYTHONUNBUFFERED="1"),
    )
    lines: queue.Queue[str | None] = queue.Queue()
    said: list[str] = []

    def drain() -> None:
        assert proc.stderr is not None
        for line in proc.stderr:
            said.append(line)
            lines.put(line)
        lines.put(None)

    threading.Thread(target=drain, daemon=True).start()
    try:
        url = _served_url(lines, said, name, url_pattern)
        yield url, proc
        proc.send_signal(signal.SIGINT)
        assert proc.wait(20) == 0, "".join(said)
        assert "Traceback" not in "".join(said), "".join(said)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(10)


def _served_url(
    lines: queue.Queue[str | None], said: list[str], name: str, url_pattern: str
) -> str:
    while True:
        try:
            line = lines.get(timeout=READY_TIMEOUT_S)
        except queue.Empty:
            raise AssertionError(f"the {name} never served: {''.join(said)}") from None
        if line is None:
            raise AssertionError(f"the {name} stopped: {''.join(said)}")
        found = re.search(url_pattern, line)
        if line.startswith(f"dms: {name} on ") and found:
            return found.group(0)


class EventStream:
    """The viewer's ``/events`` read as server-sent events, in a thread; every event kept.
    ``url``: the page's, with its token."""

    def __init__(self, url: str) -> None:
        self.events: list[tuple[str, Any]] = []
        self._cond = threading.Condition()
        self._response = urllib.request.urlopen(at(url, "events"), timeout=READY_TIMEOUT_S)
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        name, data = "message", []
        try:
            for raw in self._response:
                line = raw.decode().rstrip("\n")
                if line.startswith("event: "):
                    name = line[7:]
                elif line.startswith("data: "):
                    data.append(line[6:])
                elif not line and data:
                    with self._cond:
                        self.events.append((name, json.loads("\n".join(data))))
                        self._cond.notify_all()
                    name, data = "message", []
        except (OSError, ValueError, AttributeError):  # closed under the reader by close()
            return

    def wait_for(self, name: str, predicate: Callable[[Any], bool], timeout: float = 10.0) -> Any:
        """The first ``name`` event so far, or to come, whose data satisfies ``predicate``."""
        found: list[Any] = []

        def ready() -> bool:
            found[:] = [d for n, d in self.events if n == name and predicate(d)][:1]
            return bool(found)

        with self._cond:
            if not self._cond.wait_for(ready, timeout):
                seen = [n for n, _ in self.events[-10:]]
                raise AssertionError(f"no matching {name} event within {timeout}s; last {seen}")
        return found[0]

    def close(self) -> None:
        self._response.close()


def browser_missing() -> str | None:
    if not CHROMIUM.exists():
        return f"no Chromium at {CHROMIUM} (apt-get install chromium)"
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        return "the playwright package is not installed (pip install -e '.[dev]')"
    return None


def watch_lit(page: Any) -> None:
    """Keep, in ``window.litSeen``, each state lit on the canvas, in turn."""
    page.evaluate(
        """() => {
          window.litSeen = [];
          const box = document.getElementById('trial-state');
          new MutationObserver(() => {
            const path = box.dataset.path;
            const lit = path && document.querySelector(`.state.lit[data-path="${path}"]`);
            const last = window.litSeen[window.litSeen.length - 1];
            if (lit && last !== path) window.litSeen.push(path);
          }).observe(box, {attributes: true, childList: true, characterData: true, subtree: true});
        }"""
    )
