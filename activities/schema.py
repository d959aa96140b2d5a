"""The published JSON Schema of behavior files, made from the parameters' models.

An editor validates behavior files with it (``activities/behavior.schema.json``,
written by ``dms behavior schema``); each state is one of the blocks or containers,
its parameters as :mod:`activities.blocks` and :mod:`activities.spec` declare them.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from activities.blocks import BLOCKS, AttendParams, BlockParams, accepts_any_string
from activities.declaration import declaration_schema
from activities.spec import CONTAINER_PARAMS
from activities.template import PLACEHOLDER

PLACEHOLDER_SCHEMA = {"type": "string", "pattern": rf"^\s*{PLACEHOLDER.pattern}\s*$"}
"""A value that is exactly one placeholder: allowed for a parameter of any type."""


def _written(prop: dict[str, Any], bound: bool) -> dict[str, Any]:
    """A parameter's JSON Schema as pydantic makes it, as a file may write it: with a
    placeholder allowed if it is ``bound`` on entry, without pydantic's titles, the
    description and default last."""
    core = {k: v for k, v in prop.items() if k not in ("title", "description", "default")}
    notes: dict[str, Any] = {k: prop[k] for k in ("description", "default") if k in prop}
    if bound and not accepts_any_string(core):
        options = core["anyOf"] if set(core) == {"anyOf"} else [core]
        core = {"anyOf": [*options, PLACEHOLDER_SCHEMA]}
    return {**core, **notes}


def _params_schema(model: type[BlockParams]) -> dict[str, Any]:
    """The JSON Schema of a block's (or container's) parameters, from its model."""
    generated = model.model_json_schema()
    assert "$defs" not in generated, f"{model.__name__}: nested models are not supported"
    props: dict[str, Any] = {}
    for key, prop in generated["properties"].items():
        if key == "states":
            props[key] = {"type": "object", "additionalProperties": {"$ref": "#/$defs/state"}}
        elif key == "state":
            props[key] = {
                "type": "object",
                "additionalProperties": {"$ref": "#/$defs/state"},
                "minProperties": 1,
                "maxProperties": 1,
            }
        else:
            props[key] = _written(prop, model.may_bind(key))
    return {
        "type": "object",
        "properties": props,
        "required": generated.get("required", []),
        "additionalProperties": False,
    }


def json_schema() -> dict[str, Any]:
    """The published JSON Schema of behavior files (``dms behavior schema``)."""
    state_variants = []
    names = {"type": "array", "items": {"type": "string"}}
    for block, model in [
        *((b, cls.PARAMS) for b, cls in BLOCKS.items()),
        *CONTAINER_PARAMS.items(),
    ]:
        body = _params_schema(model)
        doc = BLOCKS[block].DOC if block in BLOCKS else f"Container: {block}. {model.__doc__}"
        state_variants.append(
            {
                "type": "object",
                "description": doc,
                "properties": {
                    block: body,
                    "transitions": {"type": "object", "additionalProperties": {"type": "string"}},
                    "input_keys": names,
                    "output_keys": names,
                    "remapping": {"type": "object", "additionalProperties": {"type": "string"}},
                },
                "required": [block],
                "additionalProperties": False,
            }
        )
    triple = {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3}
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "$id": "https://github.com/dms/activities/behavior.schema.json",
        "title": "dms behavior",
        "description": "A behavior of the Mini robot: a hierarchical state machine of blocks.",
        "type": "object",
        "properties": {
            "name": {"type": "string", "minLength": 1},
            "description": {"type": "string"},
            "attend": {
                "description": "The gaze kept on a frame while the behavior runs: its name "
                "(user, face:<id>, object:<name>) or the attend block's settings.",
                "oneOf": [{"type": "string"}, _params_schema(AttendParams)],
            },
            "frames": {
                "description": "Task frames: places relative to a detected marker or object "
                "(of), moved by xyz (metres) and rpy (radians); kept at their last known place "
                "when the marker is lost. look_at, point_at and gesture aim at them by name.",
                "type": "object",
                "additionalProperties": {
                    "type": "object",
                    "properties": {
                        "of": {"type": "string"},
                        "xyz": triple,
                        "rpy": triple,
                    },
                    "required": ["of"],
                    "additionalProperties": False,
                },
            },
            "activity": declaration_schema(),
            "outcomes": names,
            "initial": {"type": "string"},
            "userdata": {"type": "object"},
            "states": {"type": "object", "additionalProperties": {"$ref": "#/$defs/state"}},
        },
        "required": ["name", "outcomes", "states"],
        "additionalProperties": False,
        "$defs": {"state": {"oneOf": state_variants}},
    }


SCHEMA_PATH = Path(__file__).with_name("behavior.schema.json")


def schema_text() -> str:
    return json.dumps(json_schema(), indent=2) + "\n"
