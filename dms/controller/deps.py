"""What the controller works with (:class:`ControllerDeps`) and what it counts."""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, TypeVar

from activities import BehaviorLibrary
from dms.kernel.expression import ExpressionArbiter
from dms.scene import Scene
from motivation import MotivationModel

if TYPE_CHECKING:  # the daemon opens its store and agenda after ready: not imported here
    from agenda import Agenda
    from dms.interactions import InteractionLog
    from dms.profiles import ProfileService
    from dms.rules import LiveRules
    from memory import ActivityChooser, QuestionBank

T = TypeVar("T")

log = logging.getLogger(__name__)


@dataclass
class ControllerDeps:
    """Everything the controller works with; the daemon and the simulator build it."""

    library: BehaviorLibrary
    expression: ExpressionArbiter
    motivation: MotivationModel
    profiles: ProfileService | None = None
    agenda: Agenda | None = None
    rules: LiveRules | None = None
    chooser: ActivityChooser | None = None
    questions: QuestionBank | None = None
    report_error: Callable[[str, str], None] = lambda key, error: None
    robot_state: Callable[[], Mapping[str, Any]] = dict
    scene: Scene | None = None
    """The frames behaviors aim at (the user's face, objects, the body); None: no gaze."""
    interactions: InteractionLog | None = None
    """Told what each tick did (its decisions and inputs): the sessions' interaction events."""


@dataclass
class Counters:
    """Running totals for metrics and studies, read by anyone, counted through its
    methods (one for each thing that happens: the tallies are this object's own)."""

    ticks: int = 0
    decisions: int = 0
    activity_failures: int = 0
    not_loaded: int = 0
    unanswered: int = 0
    misheard: int = 0
    """Utterances under ``min_speech_confidence``: speech recognition errors."""
    by_reason: dict[str, int] = field(default_factory=dict)

    def count_tick(self) -> None:
        self.ticks += 1

    def count_decision(self, reason: str) -> None:
        self.by_reason[reason] = self.by_reason.get(reason, 0) + 1

    def count_recorded(self, decisions: int) -> None:
        """The decisions a tick's record carries."""
        self.decisions += decisions

    def count_failure(self) -> None:
        """An activity failed while it ran."""
        self.activity_failures += 1

    def count_not_loaded(self) -> None:
        """An activity did not start: its behavior would not load."""
        self.not_loaded += 1

    def count_unanswered(self) -> None:
        """A question, or the menu, had no answer."""
        self.unanswered += 1

    def count_misheard(self) -> None:
        self.misheard += 1


def agenda_call(deps: ControllerDeps, what: str, call: Callable[[Agenda], T]) -> T | None:
    """``call`` on the agenda (``what`` names it in a report); None if there is no agenda
    or the call failed.

    The agenda's database may fail: the failure is reported and the loop goes on.
    """
    if deps.agenda is None:
        return None
    try:
        return call(deps.agenda)
    except Exception as error:
        log.exception("agenda.%s failed", what)
        deps.report_error("agenda", f"{what}: {error}")
        return None
