"""A fitted mu or e far from a given drop-test calibration is said, not only shown: a
black-box probe's sweep (e 0.5) was fitted e 0.599 beside a calibration of 0.500
[0.4998, 0.5002], and the diagnosis said nothing of it."""

from __future__ import annotations

from bouncelab.gap.diagnose import CALIBRATION_DISAGREE, calibration_disagreements

CAL = {"mu": 0.2, "mu_ci": [0.1997, 0.2003], "restitution": 0.5, "restitution_ci": [0.4998, 0.5002]}


def test_a_fitted_e_far_from_the_calibration_is_warned_of():
    lines = calibration_disagreements(CAL, {"e": 0.5991, "mu": 0.193})
    assert lines == [
        "the fitted e 0.5991 is +20 % from the drop-test calibration's 0.5 [0.4998, 0.5002]: "
        "the sweep and the drop test disagree (another body or guide, an impact that lasts, "
        "or an effect standing in for another); --fix-calibration holds the calibrated values"
    ]


def test_within_the_goal_or_the_interval_or_not_fitted_nothing_is_said():
    near = 0.5 * (1 + 0.9 * CALIBRATION_DISAGREE)
    assert calibration_disagreements(CAL, {"e": near, "mu": 0.2}) == []
    wide = {**CAL, "restitution_ci": [0.3, 0.7]}
    assert calibration_disagreements(wide, {"e": 0.6}) == []
    assert calibration_disagreements(CAL, {"k": 3.0, "a": 0.1}) == []  # neither mu nor e
    no_ci = {"mu": 0.2, "restitution": 0.5}
    assert len(calibration_disagreements(no_ci, {"mu": 0.3})) == 1
