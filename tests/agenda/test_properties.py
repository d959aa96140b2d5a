"""Every occurrence ends delivered or missed exactly once, whatever the user and daemon do."""

from __future__ import annotations

import itertools
from datetime import timedelta
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from agenda import Agenda, ItemSpec, Outcome
from tests.agenda.conftest import START

STEP = timedelta(seconds=30)
BLOCK = 20  # ticks of 30 s: presence and downtime change every 10 minutes
_EXAMPLES = itertools.count()


@settings(
    max_examples=40,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(
    every=st.integers(60, 3600),
    lead_part=st.floats(0, 0.9),
    grace=st.integers(0, 5400),
    blocks=st.lists(st.sampled_from(["present", "away", "down"]), min_size=1, max_size=18),
)
def test_occurrences_are_accounted_for_once(
    tmp_path: Path, every: int, lead_part: float, grace: int, blocks: list[str]
) -> None:
    url = f"sqlite:///{tmp_path / f'example{next(_EXAMPLES)}.db'}"
    lead = int(every * lead_part)
    agenda = Agenda.open(url)
    agenda.add(
        ItemSpec(user_id="ann", kind="reminder", text="x", every=every, lead_s=lead, grace_s=grace),
        START,
    )
    now = START
    delivered_windows: list[bool] = []
    running = True
    for block in blocks:
        for _ in range(BLOCK):
            now += STEP
            if block == "down":
                if running:
                    agenda.close()
                    running = False
                continue
            if not running:
                agenda = Agenda.open(url)
                agenda.recover(now)
                running = True
            for item in agenda.due(now, "ann" if block == "present" else None):
                fire = item.fire_time
                delivered_windows.append(
                    fire - timedelta(seconds=lead) <= now <= fire + timedelta(seconds=grace)
                )
                agenda.delivered(item, now)
    if not running:
        agenda = Agenda.open(url)
    agenda.due(now, None)
    log = agenda.history("ann")
    agenda.close()

    assert all(delivered_windows)
    covered: list[int] = []
    for entry in log:
        first = int((entry.fire_time - START).total_seconds())
        last = int((entry.last_fire_time - START).total_seconds())
        assert first % every == 0 and last % every == 0
        fires = list(range(first, last + 1, every))
        assert len(fires) == entry.count
        if entry.outcome is Outcome.DELIVERED:
            assert entry.count == 1
        covered.extend(fires)
    assert len(covered) == len(set(covered)), "an occurrence was accounted for twice"
    end = int((now - START).total_seconds())
    # Resolved by the last call: an occurrence past its grace or superseded by the next.
    must = {
        f for f in range(every, end + 1, every) if min(f + grace + 1e-6, f + every - lead) <= end
    }
    assert must <= set(covered)
