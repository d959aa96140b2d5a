"""The simulated study reproduces the seed's Table 4 from its inputs (issue 12, item 4).

The default study (participants like the seed's, 30 minutes each, moderate proactivity)
must put every one of the eight metrics within 20 % of the paper's mean and the failures
in the paper's order of magnitude. The inputs are calibrated (content lengths, the
participants' pace and patience, the robot's launch delay); the decision logic is the
daemon's own and knows nothing of the study (test_study_guard.py).

Two runs of 30 sessions (seeds 0 and 1) are pooled: one run of 30 cannot hold the
counts to 20 %. Cancels, 0.53 a session, are whole numbers per session, so their
30-session mean has a standard error of at least 0.09 (every session 0 or 1 cancel),
0.19 as simulated (a third of the mean) whatever the inputs; robot decisions 13 % of
the mean, user selections and the time between activities 8-9 % (seed 0).
"""

from __future__ import annotations

from sim.study import PAPER, StudyResult, run_study, study_settings


def test_the_default_study_lands_within_20_percent_of_every_table4_mean() -> None:
    runs = [run_study(30, 30.0, "moderate", seed, study_settings()) for seed in (0, 1)]
    pooled = StudyResult(
        [s for run in runs for s in run.sessions], 0.0, 30.0, "moderate", 0
    ).to_json()
    off = {
        key: round(pooled[key] / mean - 1.0, 3)
        for key, (mean, _sd) in PAPER.items()
        if abs(pooled[key] / mean - 1.0) > 0.20
    }
    assert not off, f"metrics more than 20 % from the paper's mean: {off}"
    for run in runs:
        failures = run.to_json()["failures"]
        assert failures["speech_recognition_errors"] <= 15  # the paper: 5 in 30 sessions
        assert failures["user_not_answering"] <= 3  # the paper: 0
        assert failures["activity_not_loaded"] == 0  # every shipped behavior loads
