"""``--proactivity`` sets the participants' true proactivity, and the initiative follows.

A low-proactivity participant leaves the menu's choice to the robot; a high one picks,
and asks for favourites by name. The daemon learns which from what they do (it is not
told): low gives at least twice as many robot decisions as user selections from the
first visit; high the reverse once the daemon has met them (on a first visit it has no
estimate yet and mixes both, as for anyone new).
"""

from __future__ import annotations

from sim.study import run_study, study_settings


def test_low_proactivity_lets_the_robot_choose() -> None:
    result = run_study(8, 30.0, "low", 1, study_settings())
    robot = sum(s.robot_decisions for s in result.sessions)
    user = sum(s.user_selections for s in result.sessions)
    assert robot >= 2 * user, (robot, user)


def test_high_proactivity_takes_the_initiative_once_known() -> None:
    result = run_study(6, 30.0, "high", 1, study_settings(), repeat=3)
    later = [s for s in result.sessions if s.visit >= 2]
    robot = sum(s.robot_decisions for s in later)
    user = sum(s.user_selections for s in later)
    assert user >= 2 * robot, (robot, user)
    first = [s for s in result.sessions if s.visit == 1]
    assert sum(s.user_selections for s in later) > sum(s.user_selections for s in first)
