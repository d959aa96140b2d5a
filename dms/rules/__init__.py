"""DMSL, the decision rule language ("Combining Finite State Machine and Decision-Making Tools
for Adaptable Robot Behavior"; docs/dmsl.md).

Designers write ``.dmsl`` files of ``def``s and ``component`` blocks; the daemon asks a
component for a decision with ``params.user``, ``params.robot`` and ``params.env``::

    rules = load_rules([Path("obstacle.dmsl")])
    rules.evaluate("ObstacleDetected", {"user": {...}, "robot": {...}, "env": {...}})
    # RuleResult(activate=("plan",), cancel=(), missing=("user.age",))

Modules: ``dmsl.lark`` and :mod:`.parser` (text to :mod:`.nodes`), :mod:`.printer`
(back to text), :mod:`.compiler` (closures, :class:`RuleSet`), :mod:`.verifier`,
:mod:`.schema`, :mod:`.loader`. Errors: :class:`RulesError` (a ``DmsError``) carries
every :class:`Problem`.
"""

from dms.rules.compiler import Params, RuleResult, RuleSet
from dms.rules.loader import (
    LiveRules,
    check_files,
    check_outcomes,
    lint_files,
    load_rules,
    rules_from_text,
)
from dms.rules.parser import parse
from dms.rules.problems import Problem, RulesError
from dms.rules.schema import ParameterSchema

__all__ = [
    "LiveRules",
    "ParameterSchema",
    "Params",
    "Problem",
    "RuleResult",
    "RuleSet",
    "RulesError",
    "check_files",
    "check_outcomes",
    "lint_files",
    "load_rules",
    "parse",
    "rules_from_text",
]
