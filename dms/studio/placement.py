"""Where the designer placed states by hand: a sidecar beside the behavior's file.

``NAME.layout.json`` holds ``{"positions": {"PATH": [x, y]}}``, each state's top left
inside its container, in the canvas's units. The behavior's YAML is never touched by a
placement (it stays byte-identical, and the daemon, which reads only ``*.yaml``, never
sees the sidecar). A sidecar that cannot be read is ignored with its reason, never
fatal: the states are then laid out automatically.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from dms.studio.errors import StudioError

SUFFIX = ".layout.json"
MAX_POSITIONS = 2000
"""More states than any behavior has: a bound on what a request may write."""
MAX_COORDINATE = 1e6
MAX_PATH = 400
MAX_BYTES = 500_000


Positions = dict[str, tuple[float, float]]


def sidecar(yaml_path: Path) -> Path:
    """The sidecar of ``NAME.yaml``: ``NAME.layout.json`` in the same folder."""
    return yaml_path.with_name(yaml_path.stem + SUFFIX)


def parse(value: Any, where: str = "layout") -> Positions:
    """The positions in ``value`` (``{"positions": {...}}``), checked and bounded.

    Raises:
        StudioError: naming what is wrong (a request's; a file's is ignored by :func:`read`).
    """
    if value is None:
        return {}
    positions = value.get("positions") if isinstance(value, dict) else None
    if not isinstance(positions, dict):
        raise StudioError(f'{where}: {{"positions": {{"STATE/PATH": [x, y], ...}}}}')
    if len(positions) > MAX_POSITIONS:
        raise StudioError(f"{where}: at most {MAX_POSITIONS} positions")
    out: Positions = {}
    for path, point in positions.items():
        if not isinstance(path, str) or not 0 < len(path) <= MAX_PATH:
            raise StudioError(f"{where}: a state path of 1 to {MAX_PATH} characters")
        if not (
            isinstance(point, list)
            and len(point) == 2
            and all(_coordinate(number) for number in point)
        ):
            raise StudioError(f"{where}: {path!r}: [x, y], two finite numbers")
        out[path] = (float(point[0]), float(point[1]))
    return out


def _coordinate(number: Any) -> bool:
    return (
        isinstance(number, int | float)
        and not isinstance(number, bool)
        and math.isfinite(number)
        and abs(number) <= MAX_COORDINATE
    )


def read(yaml_path: Path) -> tuple[Positions, str | None]:
    """The positions kept beside ``yaml_path`` (none when there is no sidecar), and why
    the sidecar was ignored, if it was."""
    path = sidecar(yaml_path)
    try:
        if path.stat().st_size > MAX_BYTES:
            return {}, f"{path.name} is over {MAX_BYTES} bytes: ignored"
        data = json.loads(path.read_text(encoding="utf-8"))
        return parse(data, path.name), None
    except FileNotFoundError:
        return {}, None
    except (OSError, UnicodeDecodeError, ValueError) as error:
        return {}, f"{path.name} is not readable JSON ({error}): ignored"
    except StudioError as error:
        return {}, f"{error}: ignored"


def text(positions: Positions) -> str:
    """The sidecar's text: sorted, one state a line, so that a diff reads well."""
    rows = [
        f"    {json.dumps(path)}: [{_number(x)}, {_number(y)}]"
        for path, (x, y) in sorted(positions.items())
    ]
    inner = ",\n".join(rows)
    return '{\n  "positions": {\n' + inner + ("\n" if rows else "") + "  }\n}\n"


def _number(value: float) -> str:
    return str(int(value)) if float(value).is_integer() else f"{value:.1f}"


def to_json(positions: Positions) -> dict[str, Any]:
    return {"positions": {path: [x, y] for path, (x, y) in positions.items()}}
