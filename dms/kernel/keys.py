"""Key expressions of the public Zenoh key space (docs/contract.md), as named constants.

Keys are relative to ``robots/<robot_id>/``; :func:`absolute` makes them whole.
"""

from __future__ import annotations

import re

ROBOT_ID_RE = re.compile(r"[a-z0-9_-]+")
"""A robot id, matched whole (``fullmatch``): with ``match`` and ``$`` an id ending in a
line break would pass."""

# Into the daemon: state-like inputs (the latest value counts) ...
PERCEPTION_USER = "perception/user"
PARAMS_ROBOT = "params/robot"
PARAMS_ENV = "params/env"
# ... optional state inputs (shown in the state only once a module declares or sends them) ...
PERCEPTION_OBJECTS = "perception/objects"
ROBOT_JOINTS = "robot/joints"
# ... and event inputs (each message counts once).
PERCEPTION_TOUCH = "perception/touch"
PERCEPTION_SPEECH = "perception/speech"
PERCEPTION_SCREEN = "perception/screen"
REQUEST = "request"
ROBOT_FEEDBACK = "robot/feedback"

STATE_INPUTS = (PERCEPTION_USER, PARAMS_ROBOT, PARAMS_ENV)
OPTIONAL_INPUTS = (PERCEPTION_OBJECTS, ROBOT_JOINTS)
EVENT_INPUTS = (PERCEPTION_TOUCH, PERCEPTION_SPEECH, PERCEPTION_SCREEN, REQUEST, ROBOT_FEEDBACK)
INPUT_KEYS = STATE_INPUTS + OPTIONAL_INPUTS + EVENT_INPUTS
"""Every input, event inputs last: ``InputBoard.take`` lists the state inputs, then the
event inputs, so ``DmsState.inputs`` keeps this order."""
URGENT_INPUTS = frozenset({PERCEPTION_TOUCH, PERCEPTION_SCREEN, PERCEPTION_SPEECH, REQUEST})
"""Inputs acted on at once, not at the next tick."""

# Out of the daemon.
DMS_STATE = "dms/state"
DMS_DECISION = "dms/decision"
DMS_ERRORS = "dms/errors"
DMS_BEHAVIOR = "dms/behavior"
ROBOT_COMMAND = "robot/command"

# Queryables with a trailing segment.
USERS_PREFIX = "users/"
AGENDA_PREFIX = "agenda/"
ALL_USERS = ("*", "**", "")
"""What follows ``users/`` or ``agenda/`` in a query for every user's data."""

# Liveliness.
ALIVE_PREFIX = "alive/"
ALIVE_DMS = "alive/dms"


def absolute(robot_id: str, key: str) -> str:
    """``robots/<robot_id>/<key>``."""
    return f"robots/{robot_id}/{key}"


def relative(robot_id: str, key_expr: str) -> str | None:
    """The key after ``robots/<robot_id>/``, or None when it is not this robot's."""
    prefix = f"robots/{robot_id}/"
    return key_expr[len(prefix) :] if key_expr.startswith(prefix) else None
