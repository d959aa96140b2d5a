"""Names a behavior gives the robot, checked at load: frames, gestures, LED patterns, faces,
and the texts it must be given.

A state can name something the robot will never find: a frame that cannot exist (the
state ends ``lost`` at once), a gesture, an LED pattern or a screen face the robot does
not have (it does nothing visible). The loader refuses these per file, one message per
parameter, against the frames that can exist and the robot's repertoire
(:mod:`dms.kernel.repertoire`). A value with a placeholder is not checked here: it is
known once bound. A required text left empty (a ``speak`` with ``text: ""``) is refused
too: the robot would say nothing, and nobody would know why.
"""

from __future__ import annotations

import difflib
import re
from collections.abc import Mapping, Sequence
from typing import Any

from activities.blocks import BLOCKS
from activities.gaze import USER
from activities.template import PLACEHOLDER
from dms.kernel.body import HEAD, LEFT_SHOULDER, NECK, RIGHT_SHOULDER, TORSO
from dms.kernel.frames import BASE, FACE_PREFIX, OBJECT_PREFIX
from dms.kernel.ids import InvalidIdentifier, check_identifier
from dms.kernel.repertoire import FACES, GESTURES, LED_PATTERNS

FIXED_FRAMES = (USER, BASE, TORSO, NECK, HEAD, LEFT_SHOULDER, RIGHT_SHOULDER)
"""Frames with a fixed name: whoever is in front, and the robot's own."""
FRAME_KINDS = "user, face:<user id>, object:<name>, base, torso, neck, head, shoulder:left|right"
OBJECT_NAME = re.compile(r"[A-Za-z0-9_.-]{1,64}")
"""What perception may call an object (``perception/objects``)."""
FRAME_PARAMS: dict[str, str] = {
    "look_at": "frame",
    "point_at": "frame",
    "attend": "frame",
    "gesture": "toward",
}
"""The blocks that aim at a frame, and the parameter that names it."""
NAMED: dict[tuple[str, str], tuple[str, tuple[str, ...]]] = {
    ("gesture", "name"): ("gesture", GESTURES),
    ("leds", "pattern"): ("LED pattern", LED_PATTERNS),
    ("show", "face"): ("face", FACES),
}
"""(block, parameter): what the value names, and the names the robot has."""


def _did_you_mean(word: str, names: Sequence[str]) -> str:
    close = difflib.get_close_matches(word, list(names), n=1, cutoff=0.6)
    return f"; did you mean {close[0]!r}?" if close else ""


def frame_problem(frame: str) -> str | None:
    """Why a frame of this name can never be known, or None when it can."""
    if frame in FIXED_FRAMES:
        return None
    if frame.startswith(FACE_PREFIX):
        try:
            check_identifier(frame.removeprefix(FACE_PREFIX), "user id")
        except InvalidIdentifier as error:
            return f"frame {frame!r} cannot exist: {error}"
        return None
    if frame.startswith(OBJECT_PREFIX):
        if OBJECT_NAME.fullmatch(frame.removeprefix(OBJECT_PREFIX)):
            return None
        return f"frame {frame!r} cannot exist: an object's name is 1 to 64 of A-Z a-z 0-9 _ . -"
    hint = _did_you_mean(frame, FIXED_FRAMES)
    if not hint and OBJECT_NAME.fullmatch(frame):
        hint = f"; did you mean {OBJECT_PREFIX + frame!r}?"
    return f"frame {frame!r} cannot exist{hint} (frames: {FRAME_KINDS})"


def value_problems(block: str, params: Mapping[str, Any]) -> list[tuple[str, str]]:
    """``(parameter, message)`` for names in a state's parameters that the robot cannot
    know: a frame, a gesture, an LED pattern, a face. A placeholder is not checked here."""
    found = empty_problems(block, params)
    key = FRAME_PARAMS.get(block)
    frame = params.get(key) if key is not None else None
    if key is not None and isinstance(frame, str) and not PLACEHOLDER.search(frame):
        problem = frame_problem(frame)
        if problem is not None:
            found.append((key, f"{block}: parameter {key!r}: {problem}"))
    for (named_block, param), (what, names) in NAMED.items():
        value = params.get(param)
        if block != named_block or not isinstance(value, str) or PLACEHOLDER.search(value):
            continue
        if any(param == empty for empty, _ in found):
            continue  # refused as empty already
        if value not in names:
            hint = _did_you_mean(value, names) or f" (the robot's: {', '.join(names)})"
            message = f"the robot has no {what} {value!r}{hint}"
            found.append((param, f"{block}: parameter {param!r}: {message}"))
    return found


def empty_problems(block: str, params: Mapping[str, Any]) -> list[tuple[str, str]]:
    """``(parameter, message)`` for each required text of the block written empty (or
    blank): a required parameter has no default because nothing can stand in for it."""
    model = BLOCKS[block].PARAMS if block in BLOCKS else None
    if model is None:
        return []
    found: list[tuple[str, str]] = []
    for name, info in model.model_fields.items():
        value = params.get(name)
        if info.is_required() and isinstance(value, str) and not value.strip():
            message = f"{block}: parameter {name!r} is empty: write it (it is required)"
            found.append((name, message))
    return found
