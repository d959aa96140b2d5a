"""The parameter schema: which ``params.user|robot|env`` names exist and their kinds.

The daemon writes its own (``dms rules schema``) so that ``dms rules check --schema``
catches a misspelled parameter and a comparison of the wrong kind.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, ValidationError

from dms.rules.nodes import Pos
from dms.rules.problems import Problem, RulesError

TypeName = Literal["number", "string", "boolean", "set"]


class ParameterSchema(BaseModel):
    """``{"user": {name: type}, "robot": {...}, "env": {...}}``; types are
    ``number``, ``string``, ``boolean`` or ``set``."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    user: dict[str, TypeName] = {}
    robot: dict[str, TypeName] = {}
    env: dict[str, TypeName] = {}

    def profile(self, name: str) -> dict[str, TypeName]:
        """The parameters of one profile (``user``, ``robot`` or ``env``)."""
        found: dict[str, TypeName] = getattr(self, name)
        return found

    @classmethod
    def load(cls, path: Path) -> ParameterSchema:
        """Read a schema JSON file.

        Raises:
            RulesError: the file cannot be read or is not a valid schema.
        """
        where = Pos(str(path), 1, 1)
        try:
            text = Path(path).read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as error:
            raise RulesError([Problem.at(where, f"cannot read schema: {error}")]) from None
        try:
            return cls.model_validate(json.loads(text))
        except json.JSONDecodeError as error:
            raise RulesError(
                [Problem(str(path), error.lineno, error.colno, f"schema is not JSON: {error.msg}")]
            ) from None
        except ValidationError as error:
            first = error.errors()[0]
            place = ".".join(str(part) for part in first["loc"]) or "schema"
            raise RulesError(
                [Problem.at(where, f"invalid schema: {place}: {first['msg']}")]
            ) from None

    def dump(self) -> str:
        """The schema as indented JSON text."""
        return json.dumps(self.model_dump(), indent=2, sort_keys=True) + "\n"
