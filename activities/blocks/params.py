"""Block parameters: the pydantic model a block declares, checked at load, bound on entry.

From a block's model come the loader's checks (:func:`param_problems`: unknown,
missing and mistyped parameters, one message each), the binding of placeholders when a
state is entered (:data:`BINDING`, :data:`Text`) and the block's part of the JSON
Schema of behavior files (:mod:`activities.schema`).
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Annotated, Any, ClassVar

from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    ValidationError,
    ValidationInfo,
)

from activities.template import as_text, has_placeholder, is_single_placeholder


class BlockParams(BaseModel):
    """The parameters of a block (or a container) as a behavior file writes them.

    Unknown names are refused. Frozen: one instance may serve every entry of a state.
    """

    model_config = ConfigDict(extra="forbid", frozen=True, defer_build=True)

    PLACEHOLDERS: ClassVar[frozenset[str] | None] = None
    """The parameters that may be written as a placeholder; None: all of them (a block
    binds them when its state is entered). Containers bind none but an iterator's
    ``items``."""

    @classmethod
    def may_bind(cls, key: str) -> bool:
        """Whether parameter ``key`` may be written as a placeholder."""
        return cls.PLACEHOLDERS is None or key in cls.PLACEHOLDERS


BINDING: dict[str, bool] = {"binding": True}
"""The validation context of a state's entry, where placeholders have been bound."""


def _bound_text(value: Any, info: ValidationInfo) -> Any:
    """A bound value read as text (``8``, ``a, b and c``); a value written in the file
    itself must be a string already (the loader validates without this context)."""
    if info.context is BINDING and value is not None and not isinstance(value, str):
        return as_text(value)
    return value


Text = Annotated[str, BeforeValidator(_bound_text)]
"""A string; a placeholder that binds to another value gives that value as text."""


def accepts_any_string(schema: Mapping[str, Any]) -> bool:
    """Whether a JSON Schema takes every string (a placeholder then needs no mention)."""
    if "anyOf" in schema:
        return any(accepts_any_string(option) for option in schema["anyOf"])
    constrained = {"enum", "const", "pattern", "minLength", "maxLength", "format"}
    kind = schema.get("type")
    return (kind is None or kind == "string") and not constrained & schema.keys()


_WORDS = {
    "string": "string",
    "integer": "integer",
    "number": "number",
    "boolean": "boolean",
    "object": "mapping",
    "null": "null",
}


def _expected(schema: Mapping[str, Any]) -> str:
    """What a field's JSON Schema asks for, in the words of the loader's messages."""
    if "anyOf" in schema:
        return " or ".join(_expected(option) for option in schema["anyOf"])
    kind = schema.get("type")
    if "enum" in schema:
        return f"{_WORDS.get(str(kind), 'value')} one of {list(schema['enum'])}"
    if kind == "array":
        items = schema.get("items") or {}
        return f"list of {_expected(items)}s" if items.get("type") else "list"
    return _WORDS.get(str(kind), "anything")


@dataclass(frozen=True)
class ParamFields:
    """What the loader and the binding need to know of a model, worked out once."""

    names: tuple[str, ...]
    """The parameters as written (a field's alias where it has one: ``in``)."""
    required: frozenset[str]
    text: frozenset[str]
    """Parameters that take any string: an empty one is a value, not nothing."""
    expected: dict[str, str]
    """Each parameter's type in words (``string``, ``list of strings``, ...)."""


@functools.cache
def fields_of(model: type[BlockParams]) -> ParamFields:
    properties = model.model_json_schema()["properties"]
    names = tuple(field.alias or name for name, field in model.model_fields.items())
    required = frozenset(
        field.alias or name for name, field in model.model_fields.items() if field.is_required()
    )
    text = frozenset(key for key in names if accepts_any_string(properties[key]))
    return ParamFields(names, required, text, {key: _expected(properties[key]) for key in names})


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 120 else text[:117] + "..."


def explain(
    model: type[BlockParams],
    error: ValidationError,
    values: Mapping[str, Any],
    deferred: frozenset[str] = frozenset(),
) -> list[tuple[str | None, str]]:
    """One ``(parameter, message)`` per parameter pydantic refused, in the order
    written, then the missing ones (not those in ``deferred``: written as placeholders)."""
    fields = fields_of(model)
    found: dict[str | None, str] = {}
    missing: list[tuple[str | None, str]] = []
    for detail in error.errors():
        key = str(detail["loc"][0]) if detail["loc"] else None
        if detail["type"] == "missing":
            if key not in deferred:
                missing.append((key, f"missing parameter {key!r}"))
        elif key in found:
            continue  # one message a parameter (a union fails once per option)
        elif detail["type"] == "extra_forbidden":
            found[key] = f"unknown parameter {key!r} ({', '.join(fields.names)})"
        elif key is None or key not in values:
            found[key] = detail["msg"]  # a check across parameters
        else:
            value = values[key]
            found[key] = (
                f"parameter {key!r} must be {fields.expected[key]}, "
                f"not {type(value).__name__} {_short(value)}"
            )
    order = {key: index for index, key in enumerate(values)}
    written = sorted(found.items(), key=lambda item: order.get(item[0] or "", len(order)))
    return [*written, *missing]


def holds_placeholder(value: Any) -> bool:
    """A value to bind when the state is entered: a placeholder in it, at any depth."""
    if isinstance(value, str):
        return has_placeholder(value)
    if isinstance(value, list):
        return any(holds_placeholder(item) for item in value)
    if isinstance(value, dict):
        return any(holds_placeholder(item) for item in value.values())
    return False


def param_problems(
    model: type[BlockParams], written: Mapping[str, Any]
) -> list[tuple[str | None, str]]:
    """What is wrong with parameters as written in a file: ``(parameter, message)``.

    A value that is exactly one placeholder may be of any type (where the model lets
    it be bound): it is left out here and checked once bound. Other values must fit
    exactly (strict: ``"3"`` is not a number, ``3.5`` not a string), as the JSON Schema
    says.
    """
    deferred = frozenset(
        k for k, v in written.items() if model.may_bind(k) and is_single_placeholder(v)
    )
    values = {k: v for k, v in written.items() if k not in deferred}
    try:
        model.model_validate(values, strict=True)
    except ValidationError as error:
        return explain(model, error, values, deferred)
    return []
