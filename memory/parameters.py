"""The kinds of ``params.user.*`` the profile gives to rules, for ``dms rules schema``."""

from __future__ import annotations

from memory.profile import FIELDS

KNOWN_ATTRIBUTES: dict[str, str] = {
    "occupation": "string",
    "education": "string",
    "hobbies": "string",
    "lives_alone": "boolean",
}
"""Free attributes the question bank fills, so rules may name them."""


def user_parameter_types() -> dict[str, str]:
    """``{name: "number" | "string" | "boolean" | "set"}`` for every user parameter."""
    types = {name: rule.kind for name, rule in FIELDS.items()}
    types.update(KNOWN_ATTRIBUTES)
    types["id"] = "string"
    types["likes"] = "set"
    return types
