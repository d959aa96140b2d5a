"""The studio's web side: the page, its static files and a small JSON API.

Every request passes the viewer's :class:`~dms.viewer.guard.HostGuard` (a foreign
``Host`` is 421, a write from a foreign ``Origin`` 403) and then the
:class:`~dms.viewer.auth.TokenGuard` (no token, 403; the URL with the token sets a cookie). The API:

- ``GET /api/palette``: the blocks by category with their schemas;
- ``GET /api/behaviors``: the folder and its behaviors; ``GET /api/behaviors/NAME``
  opens one (the document and its hash);
- ``POST /api/check`` ``{doc}``: the loader's messages and each state's outcomes;
- ``POST /api/save`` ``{doc, hash, layout?}``: writes the file, or a draft (409: changed
  on disk), and the states placed by hand beside it;
- ``POST /api/compare`` ``{doc}``: the file on disk and what a save would write;
- ``POST /api/try/start`` ``{doc, state?}``, ``/api/try/step``, ``/api/try/answer``
  ``{text}``, ``/api/try/stop``, ``/api/try/marker`` ``{seen}``: a trial on the simulated
  Mini (the marker on its table hidden or shown);
- ``POST /api/daemon/try`` ``{doc, state?, step?}``, ``GET /api/daemon/try?since=N``
  (its states), ``POST /api/daemon/step``, ``/api/daemon/answer`` ``{text}``,
  ``/api/daemon/stop``: a try on the daemon's robot (``--connect``), which the daemon
  may refuse;
- ``GET /api/robot?on=daemon|sim``: the robot's joints, for the Record button;
  ``POST /api/robot/pose`` ``{joints}``: poses the simulated Mini by hand (the sliders);
  ``GET /api/body``: its joints' limits;
- ``GET /api/frames``: the frames for the frame picker (the daemon's, when connected);
- ``GET /api/rules``, ``GET /api/rules/NAME``, ``POST /api/rules/check`` ``{name, text}``,
  ``POST /api/rules/save`` ``{name, text, hash}``: the rules pane.
"""

from __future__ import annotations

import json
import math
from collections.abc import Awaitable, Callable
from importlib import resources
from pathlib import Path
from typing import Any

from starlette.applications import Starlette
from starlette.concurrency import run_in_threadpool
from starlette.middleware import Middleware
from starlette.requests import Request
from starlette.responses import FileResponse, Response
from starlette.routing import Mount, Route
from starlette.staticfiles import StaticFiles

from activities.known import known_media
from activities.library import content_dirs
from dms.kernel.body import JOINTS, NEUTRAL
from dms.studio import placement
from dms.studio.bodies import json_object
from dms.studio.errors import StudioError
from dms.studio.folder import Folder
from dms.studio.handpose import HandPose
from dms.studio.link import DaemonLink
from dms.studio.palette import palette
from dms.studio.rules import RulesFiles
from dms.studio.trial import MARKER, RobotFactory, Trial, one_state
from dms.viewer.auth import TokenGuard
from dms.viewer.guard import WILDCARDS, HostGuard, allowed_hosts

DEFAULT_FRAMES = ["user", "face:<id>", "object:<name>"]
STATIC = Path(str(resources.files("dms.studio") / "static"))

Handler = Callable[[Request], Awaitable[Any]]


def reply(data: Any, status: int = 200) -> Response:
    body = json.dumps(data, default=str, ensure_ascii=False, allow_nan=False)
    return Response(body, status, media_type="application/json")


def api(handler: Handler) -> Callable[[Request], Awaitable[Response]]:
    """A JSON endpoint: a :class:`StudioError` becomes its status and message."""

    async def endpoint(request: Request) -> Response:
        try:
            return reply(await handler(request))
        except StudioError as error:
            return reply({"error": one_line(str(error))}, error.status)

    return endpoint


def one_line(message: str) -> str:
    """A refusal on one line: YAML's and the loader's messages span several (a caret
    under the spot), and a page or a script shows the first line of what it gets."""
    return " | ".join(line.strip() for line in message.splitlines() if line.strip())


def document(data: dict[str, Any]) -> dict[str, Any]:
    doc = data.get("doc")
    if not isinstance(doc, dict):
        raise StudioError("doc: a behavior, as a JSON object")
    return doc


class Studio:
    """The state behind the API: the folder, the rules files, the daemon (if connected),
    and the trial running, if any."""

    def __init__(
        self,
        folder: Folder,
        robot_factory: RobotFactory,
        rules: RulesFiles | None = None,
        link: DaemonLink | None = None,
    ) -> None:
        self.folder = folder
        self.robot_factory = robot_factory
        self.rules = rules or RulesFiles(())
        self.link = link
        self.trial: Trial | None = None
        self.posed: dict[str, float] | None = None
        """The simulated Mini's joints as posed by hand, until a trial moves it."""

    async def palette(self, _request: Request) -> Any:
        media = await run_in_threadpool(known_media, content_dirs(self.folder.directory))
        return palette(media)

    async def behaviors(self, _request: Request) -> Any:
        return {
            "folder": str(self.folder.directory),
            "names": self.folder.names(),
            "daemon": self.link is not None,
        }

    async def open(self, request: Request) -> Any:
        return await run_in_threadpool(self.folder.open, request.path_params["name"])

    async def check(self, request: Request) -> Any:
        doc = document(await json_object(request))
        report = await run_in_threadpool(self.folder.check, doc)
        return report.to_json()

    async def save(self, request: Request) -> Any:
        data = await json_object(request)
        opened = data.get("hash")
        if opened is not None and not isinstance(opened, str):
            raise StudioError("hash: the one the open gave, or null for a new behavior")
        layout = data.get("layout")
        positions = placement.parse(layout) if layout is not None else None
        saved = await run_in_threadpool(self.folder.save, document(data), opened, positions)
        return saved.to_json()

    async def compare(self, request: Request) -> Any:
        return await run_in_threadpool(self.folder.compare, document(await json_object(request)))

    async def try_start(self, request: Request) -> Any:
        data = await json_object(request)
        doc = document(data)
        state = data.get("state")
        if isinstance(state, str) and state:
            doc = one_state(doc, state)
        if self.trial is not None:
            self.trial.stop()
        seed = data.get("seed") or 0
        if not isinstance(seed, int) or isinstance(seed, bool):
            raise StudioError("seed: a whole number, or none")
        self.posed = None  # the trial's Mini starts from neutral
        self.trial = await run_in_threadpool(Trial, self.folder, doc, self.robot_factory(0), seed)
        return await run_in_threadpool(self.trial.step)

    def _trial(self) -> Trial:
        if self.trial is None:
            raise StudioError("no trial: start one first", 409)
        return self.trial

    async def try_step(self, _request: Request) -> Any:
        return await run_in_threadpool(self._trial().step)

    async def try_answer(self, request: Request) -> Any:
        text = (await json_object(request)).get("text")
        if not isinstance(text, str):
            raise StudioError("text: what the user says, screen:CHOICE or touch:PART")
        return {"taken": await run_in_threadpool(self._trial().answer, text)}

    async def try_marker(self, request: Request) -> Any:
        seen = (await json_object(request)).get("seen")
        if not isinstance(seen, bool):
            raise StudioError("seen: true to show the marker, false to hide it")
        return {"seen": await run_in_threadpool(self._trial().show_marker, seen)}

    async def try_stop(self, _request: Request) -> Any:
        if self.trial is not None:
            await run_in_threadpool(self.trial.stop)
        return {"stopped": True}

    async def robot(self, request: Request) -> Any:
        if request.query_params.get("on") == "daemon":
            return {"joints": self._link().robot_joints(), "on": "daemon"}
        return {"joints": self._sim_joints(), "on": "sim"}

    def _sim_joints(self) -> dict[str, float]:
        if self.posed is not None:
            return dict(self.posed)
        return self.trial.joints() if self.trial is not None else dict(NEUTRAL)

    async def pose(self, request: Request) -> Any:
        joints = (await json_object(request)).get("joints")
        if not isinstance(joints, dict) or not joints:
            raise StudioError(f"joints: {{name: radians}} of {', '.join(JOINTS)}")
        posed = self._sim_joints()
        for name, angle in joints.items():
            joint = JOINTS.get(name)
            if joint is None:
                raise StudioError(f"joints: no joint {name!r} ({', '.join(JOINTS)})")
            if isinstance(angle, bool) or not isinstance(angle, int | float):
                raise StudioError(f"joints: {name}: radians, a number")
            if not math.isfinite(angle):
                raise StudioError(f"joints: {name}: a finite number of radians")
            posed[name] = round(joint.clamp(float(angle)), 3)
        self.posed = posed
        return {"joints": posed, "on": "sim"}

    async def body_limits(self, _request: Request) -> Any:
        return {
            "joints": {
                name: {"low": joint.low, "high": joint.high, "neutral": joint.neutral}
                for name, joint in JOINTS.items()
            }
        }

    async def frames(self, _request: Request) -> Any:
        if self.link is None:
            return {"frames": [*DEFAULT_FRAMES, MARKER], "on": "sim"}
        seen = await run_in_threadpool(self.link.frames)
        return {"frames": sorted({*seen, *DEFAULT_FRAMES}, key=frame_order), "on": "daemon"}

    # ---------------------------------------------------------------- the daemon

    def _link(self) -> DaemonLink:
        if self.link is None:
            raise StudioError("no daemon: start the studio with --connect ENDPOINT", 409)
        return self.link

    async def daemon_try(self, request: Request) -> Any:
        data = await json_object(request)
        doc = document(data)
        state = data.get("state")
        if state is not None and not isinstance(state, str):
            raise StudioError("state: the path of the state to run alone")
        step = data.get("step") is True
        return await run_in_threadpool(self._link().start, doc, state, step)

    async def daemon_step(self, _request: Request) -> Any:
        return await run_in_threadpool(self._link().ask, {"op": "step"})

    async def daemon_states(self, request: Request) -> Any:
        try:
            since = int(request.query_params.get("since", "0"))
        except ValueError:
            raise StudioError("since: a number") from None
        return {"states": self._link().states(max(since, 0))}

    async def daemon_answer(self, request: Request) -> Any:
        text = (await json_object(request)).get("text")
        return await run_in_threadpool(self._link().ask, {"op": "answer", "text": text})

    async def daemon_stop(self, _request: Request) -> Any:
        return await run_in_threadpool(self._link().ask, {"op": "stop"})

    # ---------------------------------------------------------------- the rules pane

    async def rules_list(self, _request: Request) -> Any:
        return {"names": self.rules.names()}

    async def rules_open(self, request: Request) -> Any:
        return await run_in_threadpool(self.rules.open, request.path_params["name"])

    async def rules_check(self, request: Request) -> Any:
        name, text = _rules_text(await json_object(request))
        return await run_in_threadpool(self.rules.check, name, text)

    async def rules_save(self, request: Request) -> Any:
        data = await json_object(request)
        name, text = _rules_text(data)
        opened = data.get("hash")
        return await run_in_threadpool(
            self.rules.save, name, text, opened if isinstance(opened, str) else None
        )


def frame_order(frame: str) -> tuple[int, str]:
    """The generic frames first, then what the daemon sees, by name."""
    return (DEFAULT_FRAMES.index(frame) if frame in DEFAULT_FRAMES else len(DEFAULT_FRAMES), frame)


def _rules_text(data: dict[str, Any]) -> tuple[str, str]:
    name, text = data.get("name"), data.get("text")
    if not isinstance(name, str) or not isinstance(text, str):
        raise StudioError("name and text: the rules file and what the pane holds")
    return name, text


def create_app(
    studio: Studio,
    token: str,
    port: int,
    host: str = "127.0.0.1",
    allow_hosts: tuple[str, ...] = (),
) -> Starlette:
    """The app serving ``studio`` on ``host:port`` behind the host guard and ``token``."""

    async def index(_request: Request) -> Response:
        return FileResponse(STATIC / "index.html", headers={"Cache-Control": "no-store"})

    hand = HandPose(studio.link)
    return Starlette(
        routes=[
            Route("/", index),
            Route("/api/palette", api(studio.palette)),
            Route("/api/behaviors", api(studio.behaviors)),
            Route("/api/behaviors/{name}", api(studio.open)),
            Route("/api/check", api(studio.check), methods=["POST"]),
            Route("/api/save", api(studio.save), methods=["POST"]),
            Route("/api/compare", api(studio.compare), methods=["POST"]),
            Route("/api/try/start", api(studio.try_start), methods=["POST"]),
            Route("/api/try/step", api(studio.try_step), methods=["POST"]),
            Route("/api/try/answer", api(studio.try_answer), methods=["POST"]),
            Route("/api/try/stop", api(studio.try_stop), methods=["POST"]),
            Route("/api/try/marker", api(studio.try_marker), methods=["POST"]),
            Route("/api/robot", api(studio.robot)),
            Route("/api/robot/pose", api(studio.pose), methods=["POST"]),
            Route("/api/robot/by-hand", api(hand.state)),
            Route("/api/robot/by-hand", api(hand.switch), methods=["POST"]),
            Route("/api/body", api(studio.body_limits)),
            Route("/api/frames", api(studio.frames)),
            Route("/api/daemon/try", api(studio.daemon_try), methods=["POST"]),
            Route("/api/daemon/try", api(studio.daemon_states)),
            Route("/api/daemon/step", api(studio.daemon_step), methods=["POST"]),
            Route("/api/daemon/answer", api(studio.daemon_answer), methods=["POST"]),
            Route("/api/daemon/stop", api(studio.daemon_stop), methods=["POST"]),
            Route("/api/rules", api(studio.rules_list)),
            Route("/api/rules/{name}", api(studio.rules_open)),
            Route("/api/rules/check", api(studio.rules_check), methods=["POST"]),
            Route("/api/rules/save", api(studio.rules_save), methods=["POST"]),
            Mount("/static", StaticFiles(directory=STATIC), name="static"),
        ],
        middleware=[
            Middleware(
                HostGuard,
                hosts=allowed_hosts(host, port, allow_hosts),
                port=port,
                any_address=host in WILDCARDS,
            ),
            Middleware(TokenGuard, token=token, page="studio", command="studio", port=port),
        ],
    )
