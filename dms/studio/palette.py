"""The palette: every block and container with its parameters' JSON Schema, by category.

Made at run time from the published JSON Schema of behavior files
(:func:`activities.schema.json_schema`), so a new block appears on the page without
touching it. A block's category is the module it is written in (``speech``,
``expression``, ...), the containers are one more. A parameter that names something of
the robot's repertoire (a gesture, an LED pattern, a face) gets the repertoire as its
``choices``: the page offers them in a list, as the loader accepts only them. A
``play_media``'s ``file`` gets the media the content files list as ``suggestions``: the
page offers them and still takes another name (the robot may hold more).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from activities.blocks import BLOCKS
from activities.names import NAMED
from activities.schema import json_schema
from activities.spec import CONTAINER_PARAMS

CATEGORY_ORDER = ("speech", "expression", "aiming", "waiting", "data", "containers")
"""The order categories are shown in; a category not named here comes after them."""

CATEGORY_TITLES = {
    "speech": "Speech and dialog",
    "expression": "Expression",
    "aiming": "Looking and pointing",
    "waiting": "Waiting",
    "data": "Data and decisions",
    "containers": "Containers",
}


def _category(block: str) -> str:
    if block in CONTAINER_PARAMS:
        return "containers"
    return BLOCKS[block].__module__.rsplit(".", 1)[-1]


SUGGESTED: dict[tuple[str, str], str] = {("play_media", "file"): "media"}
"""(block, parameter): the list of names it is offered from (free text still allowed)."""


def palette(media: Sequence[str] = ()) -> dict[str, Any]:
    """``{"categories": [{"name", "title", "blocks": [...]}, ...], "top": schema}``.

    Each block has its ``name``, ``doc``, ``outcomes`` (those of a state with its
    defaults; some blocks' depend on their parameters), ``container`` (whether it holds
    ``states`` or one ``state``) and ``schema`` (its parameters, as a file writes them).
    ``media``: the files offered for ``play_media`` (those the folder's content lists).
    """
    lists = {"media": list(media)}
    schema = json_schema()
    by_category: dict[str, list[dict[str, Any]]] = {}
    for variant in schema["$defs"]["state"]["oneOf"]:
        block = next(iter(variant["required"]))
        params = variant["properties"][block]
        props = params["properties"]
        for (named_block, param), (_what, repertoire) in NAMED.items():
            if named_block == block and param in props:
                props[param] = {**props[param], "choices": list(repertoire)}
        for (named_block, param), which in SUGGESTED.items():
            if named_block == block and param in props and lists[which]:
                props[param] = {**props[param], "suggestions": lists[which]}
        holds = "states" if "states" in props else "state" if "state" in props else None
        outcomes = list(BLOCKS[block].OUTCOMES) if block in BLOCKS else []
        by_category.setdefault(_category(block), []).append(
            {
                "name": block,
                "doc": variant.get("description", ""),
                "outcomes": outcomes,
                "container": holds,
                "schema": params,
            }
        )
    order = {name: index for index, name in enumerate(CATEGORY_ORDER)}
    names = sorted(by_category, key=lambda name: (order.get(name, len(order)), name))
    return {
        "categories": [
            {"name": name, "title": CATEGORY_TITLES.get(name, name), "blocks": by_category[name]}
            for name in names
        ],
        "top": {k: v for k, v in schema["properties"].items() if k != "states"},
    }
