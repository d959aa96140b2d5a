"""Every decision says why: what decided it (the user's tap or words, the request, the
agenda item, the motivation, the ranking, a draw with its value), read from the
decision as it is published."""

from __future__ import annotations

from dms.kernel.messages import Decision
from sim.longterm import run_longterm


def _said(decision: Decision) -> bool:
    return decision.why is not None and bool(decision.why.model_dump(exclude_none=True))


def test_every_decision_of_a_30_day_run_says_why() -> None:
    decisions = [row.decision for row in run_longterm(days=30, users=3, seed=0).decision_rows]
    assert len(decisions) > 1000
    assert [(d.action, d.reason, d.activity) for d in decisions if not _said(d)] == []
    kinds = {(d.action, d.reason) for d in decisions}
    assert {
        ("start", "user_choice"),
        ("start", "preference"),
        ("complete", "completed"),
        ("ask", "feedback"),
        ("ask", "general_question"),
        ("start", "agenda"),
    } <= kinds
    for decision in decisions:
        assert decision.why is not None
        if decision.reason == "preference":  # the ranking, with its candidates
            assert decision.why.choice is not None and decision.why.choice.ranking
        elif decision.reason == "feedback":  # the coin's value and its threshold
            assert "feedback coin" in (decision.why.evidence or ""), decision
        elif decision.reason.startswith("motivation"):
            assert decision.why.motivation is not None
        elif decision.why.evidence is not None and decision.detail:
            assert decision.detail in decision.why.evidence, decision  # what was seen
