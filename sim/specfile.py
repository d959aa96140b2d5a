"""Loading YAML specs (personas, scenarios) into pydantic models with useful errors.

The YAML is read once by the loader with line numbers (:mod:`dms.kernel.yamlfile`,
the same as behavior files'), so that every field keeps the line it came from; a
validation error is then reported as ``FILE:LINE: field: message``, naming the
innermost field that has a line.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any, TypeVar

import yaml
from pydantic import BaseModel, ValidationError

from dms.kernel.yamlfile import Path_, lines_by_path, load_located, plain, yaml_error
from sim.errors import SpecError

Model = TypeVar("Model", bound=BaseModel)


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
        located = load_located(text)
    except yaml.YAMLError as error:
        raise SpecError(yaml_error(error, where)) from None
    return plain(located), lines_by_path(located)


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
