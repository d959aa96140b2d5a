"""``dms`` as a Reachy Mini app: the robot's dashboard starts and stops the bridge.

The package declares the entry point ``reachy_mini_apps: dms``, the maker's app format:
installed into the environment of the robot's daemon (``pip install -e reachy/`` there),
it is listed on the dashboard, which runs it as ``python -m dms_reachy.app`` with the
robot already connected and stops it with SIGINT. It is the bridge with the dashboard's
connection (media on: speech through the robot's speaker), reaching a dms daemon over
Zenoh. Settings come from the environment the robot's daemon was started with:

- ``DMS_CONNECT``: the daemon's Zenoh endpoint (default ``tcp/127.0.0.1:7447``);
- ``DMS_ROBOT``: the robot id (default ``mini``);
- ``DMS_RUN``: optional, a command that runs the dms daemon itself (for example
  ``/opt/dms/.venv/bin/dms run --robot zenoh``): the app starts it first and stops it
  when it stops, so the dashboard's start button starts dms whole;
- ``DMS_REACHY_HOST``, ``DMS_REACHY_PORT``: the robot's daemon, when it does not serve
  on ``localhost:8000`` (a simulator on a port of its own).
"""

from __future__ import annotations

import os
import shlex
import subprocess
import threading
import time
from typing import Any

from reachy_mini import ReachyMini, ReachyMiniApp

DEFAULT_CONNECT = "tcp/127.0.0.1:7447"
DAEMON_WAIT_S = 60.0
"""How long the app tries to reach the dms daemon before it gives up (the dashboard then
shows its error)."""
STOP_S = 10.0


class DmsApp(ReachyMiniApp):  # type: ignore[misc]  # the SDK carries no annotations
    """The bridge, started from the robot's dashboard."""

    custom_app_url: str | None = None

    def run(self, reachy_mini: ReachyMini, stop_event: threading.Event) -> None:
        import zenoh

        from dms_reachy.__main__ import zenoh_config
        from dms_reachy.bridge import Bridge, log
        from dms_reachy.commands import ROBOT_ID_RE
        from dms_reachy.robot import Reachy

        robot = os.environ.get("DMS_ROBOT", "mini")
        if not ROBOT_ID_RE.match(robot):
            raise ValueError(f"DMS_ROBOT={robot!r}: lower-case letters, digits, _ and - only")
        connect = [os.environ.get("DMS_CONNECT", DEFAULT_CONNECT)]
        daemon = _start_daemon(os.environ.get("DMS_RUN"))
        try:
            session = _open(zenoh, zenoh_config(connect, None), stop_event)
            if session is None:
                return
            reachy = Reachy.adopt(reachy_mini, media=True)
            bridge = Bridge(robot, session, reachy)
            try:
                bridge.listen()
                log(f"app: robot {robot} over Zenoh {connect}")
                bridge.run(stop_event)
            finally:
                session.close()
        finally:
            _stop(daemon)


def _start_daemon(command: str | None) -> subprocess.Popen[bytes] | None:
    if not command:
        return None
    return subprocess.Popen(shlex.split(command))


def _stop(daemon: subprocess.Popen[bytes] | None) -> None:
    if daemon is None or daemon.poll() is not None:
        return
    daemon.terminate()
    try:
        daemon.wait(STOP_S)
    except subprocess.TimeoutExpired:
        daemon.kill()
        daemon.wait(STOP_S)


def _open(zenoh: Any, config: Any, stop_event: threading.Event) -> Any:
    """A session with the dms daemon, tried again every second while it starts."""
    give_up = time.monotonic() + DAEMON_WAIT_S
    while not stop_event.is_set():
        try:
            return zenoh.open(config)
        except zenoh.ZError:
            if time.monotonic() >= give_up:
                raise
        stop_event.wait(1.0)
    return None


def robot_daemon() -> dict[str, Any]:
    """Where the robot's daemon is, when not where the dashboard's apps look for it
    (``localhost:8000``): ``DMS_REACHY_HOST``, ``DMS_REACHY_PORT``."""
    where: dict[str, Any] = {}
    if os.environ.get("DMS_REACHY_HOST"):
        where["host"] = os.environ["DMS_REACHY_HOST"]
    if os.environ.get("DMS_REACHY_PORT"):
        where["port"] = int(os.environ["DMS_REACHY_PORT"])
    return where


if __name__ == "__main__":
    app = DmsApp()
    try:
        app.wrapped_run(**robot_daemon())
    except KeyboardInterrupt:
        app.stop()
