"""What a behavior may name besides the robot's repertoire: the robot's and the
environment's parameters (``{robot.NAME}``, ``{env.NAME}``) and the media it plays.

The parameters are those the daemon documents for ``params/robot`` and ``params/env``
(docs/contract.md) and binds in the rules (``dms rules schema``); they live here, on the
lowest floor that needs them, so that the loader, the studio and ``dms rules`` read one
list. The media are the files the content files list (the shipped ones and a folder's
own ``content``): what the simulated robot is given to play.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any, Literal

from activities.engine import read_content
from activities.errors import BehaviorError

ParameterKind = Literal["number", "string", "boolean"]

ROBOT_PARAMETERS: Mapping[str, ParameterKind] = {
    "batterylevel": "number",
    "name": "string",
    "currentroom": "string",
    "currenttask": "string",
    "obstacle": "boolean",
    "voicevolume": "number",
}
"""Robot-profile parameters the daemon provides (the robot state and ``params/robot``)."""

ENV_PARAMETERS: Mapping[str, ParameterKind] = {
    "time": "number",
    "noise_db": "number",
    "light_lux": "number",
    "currentbestpath": "boolean",
}
"""Environment parameters: ``time`` is the hour of day (0-23), the rest ``params/env``."""

PARAMETERS: Mapping[str, Mapping[str, ParameterKind]] = {
    "robot": ROBOT_PARAMETERS,
    "env": ENV_PARAMETERS,
}
"""The profile namespaces of a placeholder whose names are known, and their names."""

MAX_MEDIA = 500
"""Media files listed at most (a list to pick from, not a catalogue of a disk)."""
MAX_DEPTH = 8
"""How deep a content file is searched for ``file`` entries."""
MEDIA_KEY = "file"
"""The key a content file's media item names its file with (as ``play_media``'s)."""


def _files(value: Any, depth: int = 0) -> Iterator[str]:
    if depth > MAX_DEPTH:
        return
    if isinstance(value, Mapping):
        found = value.get(MEDIA_KEY)
        if isinstance(found, str) and found:
            yield found
        for item in value.values():
            yield from _files(item, depth + 1)
    elif isinstance(value, list):
        for item in value:
            yield from _files(item, depth + 1)


def known_media(dirs: Sequence[Path]) -> tuple[str, ...]:
    """Every media file the content files of ``dirs`` list, sorted (at most
    :data:`MAX_MEDIA`). A content file that cannot be read lists none: the loader says
    what is wrong with it elsewhere."""
    found: set[str] = set()
    names = sorted({p.stem for d in dirs if d.is_dir() for p in d.glob("*.yaml")})
    for name in names:
        try:
            found.update(_files(read_content(tuple(dirs), name)))
        except BehaviorError:
            continue
    return tuple(sorted(found)[:MAX_MEDIA])


def media_problem(file: str, media: Sequence[str]) -> str | None:
    """Why ``file`` is most likely a misspelling of a listed medium, or None.

    Only a near miss is refused: the robot may hold files no content file lists (a
    folder's own songs), but one a letter away from a listed one is a typo that would
    play nothing."""
    if file in media:
        return None
    close = difflib.get_close_matches(file, list(media), n=1, cutoff=0.8)
    if not close:
        return None
    return f"no medium {file!r} is listed; did you mean {close[0]!r}?"
