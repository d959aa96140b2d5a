"""The published JSON Schemas hold what the project ships and sends, checked by a
validator other programs use (``jsonschema``), not only by our own loader.

A designer's editor validates behavior files with ``activities/behavior.schema.json``;
a client in another language validates messages with ``dms schema DIR``'s files. Both
must accept every shipped behavior and every message the daemon builds, and refuse
what the loader refuses.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
import yaml
from jsonschema import Draft202012Validator

from activities.library import BEHAVIORS_DIR
from activities.schema import SCHEMA_PATH
from dms.kernel.messages import (
    SCHEMAS,
    ObjectsPerception,
    RobotCommand,
    RobotJoints,
    UserPerception,
    json_schema,
)

BEHAVIOR_SCHEMA = json.loads(SCHEMA_PATH.read_text())


def _behavior_validator() -> Draft202012Validator:
    Draft202012Validator.check_schema(BEHAVIOR_SCHEMA)
    return Draft202012Validator(BEHAVIOR_SCHEMA)


@pytest.mark.parametrize("path", sorted(BEHAVIORS_DIR.glob("*.yaml")), ids=lambda p: p.stem)
def test_every_shipped_behavior_is_valid_by_the_published_schema(path: Path) -> None:
    errors = list(_behavior_validator().iter_errors(yaml.safe_load(path.read_text())))
    assert not errors, [f"{'/'.join(map(str, e.path))}: {e.message}" for e in errors[:3]]


@pytest.mark.parametrize(
    "broken",
    [
        {"attend": 5},
        {"attend": {"frame": "user", "speed": 3}},
        {"states": {"A": {"look_at": {"frame": "user", "last_known": "maybe"}}}},
        {"states": {"A": {"point_at": {"arm": "left"}}}},  # frame is required
        {"states": {"A": {"gesture": {"name": "wave", "towards": "user"}}}},
    ],
)
def test_the_schema_refuses_what_the_loader_refuses(broken: dict[str, Any]) -> None:
    base: dict[str, Any] = {
        "name": "x",
        "outcomes": ["done", "lost"],
        "states": {"A": {"wait": {"seconds": 1}}},
    }
    assert not list(_behavior_validator().iter_errors(base))
    assert list(_behavior_validator().iter_errors({**base, **broken}))


MESSAGES = [
    UserPerception.model_validate(
        {
            "present": True,
            "user_id": "ann",
            "ready": True,
            "face": {
                "position": {"x": 0.6, "y": 0.2, "z": 0.35},
                "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0},
            },
        }
    ),
    ObjectsPerception.model_validate(
        {"objects": [{"name": "tag7", "pose": {"position": {"x": 0.5, "y": 0.3, "z": 0.1}}}]}
    ),
    RobotJoints.model_validate({"positions": {"neck": 0.5, "head": 0.1}, "time": None}),
    RobotCommand(
        id="cmd-1",
        channel="aim",
        action="look_at",
        args={"joints": {"neck": 0.3}, "frame": "user", "position": {"x": 0.6, "y": 0.2, "z": 0.3}},
    ),
]


@pytest.mark.parametrize("message", MESSAGES, ids=lambda m: type(m).__name__)
def test_the_frame_messages_are_valid_by_their_published_schemas(message: Any) -> None:
    name = next(key for key, model in SCHEMAS.items() if model is type(message))
    schema = json_schema(SCHEMAS[name])
    Draft202012Validator.check_schema(schema)
    assert not list(Draft202012Validator(schema).iter_errors(message.model_dump(mode="json")))


def test_a_message_schema_refuses_a_channel_or_joint_the_contract_does_not_have() -> None:
    command = json_schema(RobotCommand)
    bad = {"id": "x", "channel": "gaze", "action": "look_at", "args": {}}
    assert list(Draft202012Validator(command).iter_errors(bad))
    joints = json_schema(RobotJoints)
    for bad_joints in ({"neck": 7.0}, {"elbow": 0.1}):
        assert list(Draft202012Validator(joints).iter_errors({"positions": bad_joints}))
