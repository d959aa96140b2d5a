"""The decisions of one tick, each with its reason and why."""

from __future__ import annotations

from collections.abc import Callable, Collection
from datetime import datetime
from typing import TYPE_CHECKING, Any

from dms.controller.deps import Counters
from dms.controller.drives import Drives
from dms.kernel.activity_names import ACTIVITIES, ENTERTAINMENT_ACTIVITIES, manager_of
from dms.kernel.clock import iso
from dms.kernel.messages import (
    ChoiceWhy,
    ChosenBy,
    Decision,
    DecisionAction,
    DrawKind,
    NoveltyWhy,
    RuleWhy,
    Why,
)
from dms.kernel.session_metrics import SessionAccount

if TYPE_CHECKING:
    from memory.preferences import ChoiceDraw


class DecisionLog:
    """Collects a tick's decisions; the tick returns them in its record."""

    def __init__(
        self,
        counters: Counters,
        drives: Drives,
        account: Callable[[], SessionAccount | None],
    ) -> None:
        """``account`` gives the open session's metrics, which see every decision."""
        self.counters = counters
        self.drives = drives
        self.account = account
        self.tick = 0
        self.decisions: list[Decision] = []

    def begin(self, tick: int) -> None:
        """A new tick (or the shutdown): no decision yet."""
        self.tick = tick
        self.decisions = []

    def decide(
        self,
        action: DecisionAction,
        activity: str | None,
        reason: str,
        chosen_by: ChosenBy | None,
        detail: str | None,
        now: datetime,
        why: Why | None = None,
    ) -> None:
        """Note one decision with its ``why``: the one given, else what was seen or
        asked (:func:`evidence`); a motivated one also names the drives."""
        self.counters.count_decision(reason)
        if why is None or not why.model_fields_set:
            why = Why(evidence=evidence(action, activity, reason, detail))
        if why.motivation is None and reason.startswith("motivation"):
            why = why.model_copy(update={"motivation": self.drives.why()})
        decision = Decision(
            tick=self.tick,
            time=iso(now),
            action=action,
            activity=activity,
            manager=manager_of(activity).value if activity and activity in ACTIVITIES else None,
            reason=reason,
            chosen_by=chosen_by,
            detail=detail,
            why=why,
        )
        self.decisions.append(decision)
        account = self.account()
        if account is not None:
            account.on_decision(decision, now)


SEEN: dict[str, str] = {
    "completed": "{activity} reported it had finished",
    "user_choice": "the user chose {activity}",
    "user_request": "a request to {action} {activity}",
    "agenda": "an agenda item fell due",
    "general_question": "a general question, to fill the user's profile",
    "feedback": "asking how much the user liked {activity}",
    "confirm_cancel": "the right shoulder was touched during {activity}",
    "activity_error": "{activity} failed",
    "activity_redirect": "{activity} was asked for by the activity before",
    "user_left": "the user left",
}
"""What decided, by the decision's reason, when its caller gave no ``why`` of its own."""


def evidence(action: str, activity: str | None, reason: str, detail: str | None) -> str:
    """What decided a decision, in words: what its reason says was seen or asked (the
    request, the agenda item, the question, the touch...), with its ``detail``."""
    seen = SEEN.get(reason, reason.replace("_", " ")).format(
        action=action, activity=activity or "the activity"
    )
    return f"{seen}: {detail}" if detail else seen


def rule_why(component: str, result: Any) -> RuleWhy:
    """The rule that decided: the first ``activate`` that ran, and where it stands."""
    where = result.activated_at[0] if getattr(result, "activated_at", ()) else None
    return RuleWhy(
        component=component,
        file=where.file if where is not None else None,
        line=where.line if where is not None else None,
        activate=list(result.activate),
    )


def choice_why(excluded: Collection[str], draw: ChoiceDraw | None) -> ChoiceWhy:
    """What picked the robot's activity: the chooser's ``draw`` (its ranking, or the
    novelty coin or Thompson sampling); a draw not explained is another chooser's pick (a study's
    baseline, whose draws are its own); None, the entertainment manager's uniform one."""
    left_out = sorted(excluded) or None
    if draw is None or not draw.explained:
        by: DrawKind = "random" if draw is None else "chooser"
        candidates = [n for n in ENTERTAINMENT_ACTIVITIES if n not in excluded]
        return ChoiceWhy(
            by=by, candidates=candidates or list(ENTERTAINMENT_ACTIVITIES), excluded=left_out
        )
    if draw.ranking is not None:
        return ChoiceWhy(
            by="ranking",
            candidates=list(draw.candidates),
            excluded=left_out,
            ranking=list(draw.ranking),
        )
    novelty = None
    if draw.novelty_draw is not None:
        # unrounded: the coin is compared with its threshold, and rounding could flip it
        novelty = NoveltyWhy(
            draw=draw.novelty_draw,
            probability=draw.novelty_probability,
            untried=list(draw.untried),
        )
    samples = draw.samples
    return ChoiceWhy(
        by="novelty" if samples is None else "sampling",
        candidates=list(draw.candidates),
        excluded=left_out,
        novelty=novelty,
        samples=None if samples is None else {n: round(v, 4) for n, v in samples.items()},
    )
