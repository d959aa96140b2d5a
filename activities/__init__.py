"""Activities as behaviors: hierarchical state machines of building blocks, as in
the DMSL paper ("Combining Finite State Machine and Decision-Making Tools for Adaptable
Robot Behavior") and ROS Commander.

The managers use :class:`BehaviorLibrary` to create an :class:`Activity` from a behavior
file, then start, tick, pause, resume, cancel it and deliver perception events to it.
See ``docs/behaviors.md`` for the file format, the blocks and the containers.
"""

from activities.activity import Activity, ActivityResult, ActivityStatus
from activities.context import ActivityContext, RuleEvaluator
from activities.errors import BehaviorError
from activities.library import (
    BehaviorLibrary,
    decision_problems,
    decision_warnings,
    reload_rules_and_behaviors,
)

__all__ = [
    "Activity",
    "ActivityContext",
    "ActivityResult",
    "ActivityStatus",
    "BehaviorError",
    "BehaviorLibrary",
    "RuleEvaluator",
    "decision_problems",
    "decision_warnings",
    "reload_rules_and_behaviors",
]
