"""The simulated study reproduces the seed's Table 4 from its inputs (issue 12, item 4).

The default study (participants like the seed's, 30 minutes each, moderate proactivity)
must put every one of the eight metrics within 20 % of the paper's mean and the failures
in the paper's order of magnitude. The inputs are calibrated (content lengths, the
participants' pace and patience, the robot's launch delay, the session's protocol: its
last activity is the last that fits before the survey); the decision logic is the
daemon's own and knows nothing of the study (test_study_guard.py).

The default run (seed 0) is the issue's acceptance figure, so it is held to 20 % on its
own; the same bound on seeds 0 and 1 pooled says the means are not a lucky seed's.
Cancels, 0.53 a session, are whole numbers per session, so their 30-session mean has a
standard error of at least 0.09 (every session 0 or 1 cancel), about 0.13 as simulated
(a quarter of the mean) whatever the inputs: on seed 0 they are 19 % over, and over
seeds 0 to 9 single seeds range from -62 % to +19 % about a mean 7 % under the paper's.
"""

from __future__ import annotations

from sim.study import PAPER, StudyResult, run_study, study_settings


def test_the_default_study_lands_within_20_percent_of_every_table4_mean() -> None:
    runs = [run_study(30, 30.0, "moderate", seed, study_settings()) for seed in (0, 1)]
    pooled = StudyResult(
        [s for run in runs for s in run.sessions], 0.0, 30.0, "moderate", 0
    ).to_json()
    for name, figures in (("seed 0", runs[0].to_json()), ("seeds 0 and 1", pooled)):
        off = {
            key: round(figures[key] / mean - 1.0, 3)
            for key, (mean, _sd) in PAPER.items()
            if abs(figures[key] / mean - 1.0) > 0.20
        }
        assert not off, f"{name}: metrics more than 20 % from the paper's mean: {off}"
    for run in runs:
        failures = run.to_json()["failures"]
        assert failures["speech_recognition_errors"] <= 15  # the paper: 5 in 30 sessions
        assert failures["user_not_answering"] <= 3  # the paper: 0
        assert failures["activity_not_loaded"] == 0  # every shipped behavior loads
