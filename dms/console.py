"""How a decision reads on the console of ``dms run`` and ``dms sim``: one line each."""

from __future__ import annotations

from pathlib import Path

from dms.kernel.ids import printable
from dms.kernel.messages import Decision


def format_decision(decision: Decision) -> str:
    """One console line per decision: time, action, activity, reason, who, why.

    The detail may quote other processes (a request's ``by``, an utterance): its control
    characters are escaped, so that it cannot forge a line of the console log.
    """
    who = f" by {decision.chosen_by}" if decision.chosen_by else ""
    what = f" {decision.activity}" if decision.activity else ""
    detail = f" ({printable(decision.detail)})" if decision.detail else ""
    why = short_why(decision)
    line = f"{decision.time[11:23]} {decision.action:<8}{what} [{decision.reason}{who}]{detail}"
    return f"{line} <- {why}" if why else line


def short_why(decision: Decision) -> str:
    """The ``why`` of a decision in a few words, for the console (``dms/decision`` has all)."""
    why = decision.why
    if why is None:
        return ""
    parts = []
    if why.rule is not None:
        where = f" {Path(why.rule.file).name}:{why.rule.line}" if why.rule.file else ""
        parts.append(f"rule {why.rule.component}{where}")
    if why.mode is not None and why.mode.draw is not None and why.mode.p_user is not None:
        parts.append(f"draw {why.mode.draw:.2f} vs p_user {why.mode.p_user:.2f}")
    if why.preferences:
        parts.append("likes " + ", ".join(f"{p.activity} {p.score:.2f}" for p in why.preferences))
    if why.motivation is not None and decision.chosen_by == "motivation":
        parts.append(f"dominant {why.motivation.dominant or 'none'}")
    return "; ".join(parts)
