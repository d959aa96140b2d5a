"""Loading YAML specs (personas, scenarios) into pydantic models with useful errors.

The YAML is composed once into nodes so that every field keeps the line it came
from; a validation error is then reported as ``FILE:LINE: field: message``, naming
the innermost field that has a line.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any, TypeVar

import yaml
from pydantic import BaseModel, ValidationError

from sim.errors import SpecError

Model = TypeVar("Model", bound=BaseModel)
Path_ = tuple[str | int, ...]


def _lines(node: yaml.Node, path: Path_, out: dict[Path_, int]) -> None:
    """Record the line (1-based) of every mapping key and sequence item under ``node``."""
    if isinstance(node, yaml.MappingNode):
        for key, value in node.value:
            name = key.value if isinstance(key, yaml.ScalarNode) else str(key)
            child = (*path, name)
            out[child] = key.start_mark.line + 1
            _lines(value, child, out)
    elif isinstance(node, yaml.SequenceNode):
        for index, item in enumerate(node.value):
            child = (*path, index)
            out[child] = item.start_mark.line + 1
            _lines(item, child, out)


def read_yaml(path: Path) -> tuple[Any, dict[Path_, int]]:
    """The data of a YAML file and the line of each of its fields; SpecError if unreadable."""
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as error:
        raise SpecError(f"{path}: cannot read: {error.strerror or error}") from None
    except UnicodeDecodeError as error:
        raise SpecError(f"{path}: not UTF-8 text: {error.reason}") from None
    return parse_yaml(text, str(path))


def parse_yaml(text: str, where: str) -> tuple[Any, dict[Path_, int]]:
    """Like :func:`read_yaml` for text already read; ``where`` names it in errors."""
    try:
        node = yaml.compose(text, Loader=yaml.SafeLoader)
        data = yaml.safe_load(text)
    except yaml.MarkedYAMLError as error:
        mark = error.problem_mark or error.context_mark
        line = f":{mark.line + 1}:{mark.column + 1}" if mark is not None else ""
        raise SpecError(f"{where}{line}: not valid YAML: {error.problem or error}") from None
    except yaml.YAMLError as error:
        raise SpecError(f"{where}: not valid YAML: {error}") from None
    lines: dict[Path_, int] = {}
    if node is not None:
        _lines(node, (), lines)
    return data, lines


def line_of(lines: dict[Path_, int], loc: Sequence[str | int]) -> tuple[int | None, str]:
    """The line of the innermost located part of ``loc`` and the dotted field name."""
    parts = tuple(loc)
    field = ".".join(str(part) for part in parts) or "(top level)"
    for end in range(len(parts), 0, -1):
        line = lines.get(parts[:end])
        if line is not None:
            return line, field
    return (1 if lines else None), field


def validate(model: type[Model], data: Any, lines: dict[Path_, int], where: str) -> Model:
    """``model.model_validate(data)`` or SpecError ``FILE:LINE: field: message``."""
    if data is None:
        raise SpecError(f"{where}: the file is empty")
    try:
        return model.model_validate(data)
    except ValidationError as error:
        first = error.errors(include_url=False)[0]
        loc = [part for part in first["loc"] if not _is_tag(part)]
        line, field = line_of(lines, loc)
        at = f":{line}" if line is not None else ""
        more = f" (and {error.error_count() - 1} more)" if error.error_count() > 1 else ""
        raise SpecError(f"{where}{at}: {field}: {first['msg']}{more}") from None


def _is_tag(part: str | int) -> bool:
    # Discriminated unions add the tag name to the location; it is not a field of the file.
    return isinstance(part, str) and part.endswith("]") and "[" in part


def load_spec(model: type[Model], path: Path) -> Model:
    """Read and validate one YAML spec file."""
    data, lines = read_yaml(path)
    return validate(model, data, lines, str(path))
