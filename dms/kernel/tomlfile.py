"""Reading a TOML file, with one-line errors (the daemon's and the packages' configs)."""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

from dms.kernel.errors import ConfigError


def read_toml(path: Path) -> dict[str, Any]:
    """The tables of a TOML file; ConfigError with one line if it cannot be read or parsed."""
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as error:
        raise ConfigError(f"{path}: cannot read: {error.strerror}") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as error:
        raise ConfigError(f"{path}: not valid TOML: {error}") from None
