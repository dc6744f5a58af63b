"""The repeat rule's shifted simulations (``gap.diagnose.shifted_repeats``): the model's
per-step repeats with its Gamma a little lower and higher, aligned with the steps of
``compare_features``, so that only periodic orbits that survive the shift speak for the
data's scatter.

Reference: the ideal ball takes off at Gamma 1 (it rests below), so a step whose Gamma
shifted down falls under 1 has no flights there (NaN, not periodic); on its period-1
steps well above takeoff the orbit survives 1 %."""

from __future__ import annotations

import numpy as np
import pytest
from diag_synth import duration_s, pseudo_flights, write_run

from bouncelab.gap.diagnose import (
    REPEAT_MIN_STEPS,
    REPEAT_ROBUST_GAMMA,
    REPEAT_TOL,
    _features,
    random_force_rule,
    repeat_check,
    repeat_reason,
    shifted_repeats,
)
from bouncelab.gap.fit import make_problem
from bouncelab.physics import Model
from bouncelab.runs import load_run

IDEAL = Model.parse("ideal")


@pytest.fixture(scope="module")
def problem(tmp_path_factory):
    run_dir = write_run(tmp_path_factory.mktemp("repeat_shift"))
    flights = pseudo_flights(run_dir, IDEAL, seed=7)
    return make_problem(load_run(run_dir), flights, duration_s(), n_members=2)


def test_shifted_repeats_are_per_step_and_keep_robust_orbits(problem):
    """Shape (2, steps); every step the ideal ball repeats on at Gamma 1.1-2.0 (period 1,
    far from its first doubling) still repeats 1 % lower and higher."""
    shifted = shifted_repeats(problem, IDEAL)
    per_step = _features(problem, IDEAL)["per_step"]
    assert shifted.shape == (2, len(per_step))
    gamma = per_step["gamma"].to_numpy()
    band = (gamma > 1.1) & (gamma < 2.0)
    assert np.count_nonzero(band) >= REPEAT_MIN_STEPS
    assert np.all(per_step["repeat_sim"].to_numpy()[band] < REPEAT_TOL)
    assert np.all(shifted[:, band] < REPEAT_TOL)
    assert REPEAT_ROBUST_GAMMA == 0.01


def test_a_step_whose_shift_falls_below_takeoff_is_not_robust(problem):
    """With Gamma 30 % lower, the steps under Gamma 1 / 0.7 = 1.43 rest (NaN), so they
    leave ``model_robust``; the data's own flights are unchanged by the shift."""
    shifted = shifted_repeats(problem, IDEAL, rel=0.3)
    cmp = _features(problem, IDEAL)
    gamma = cmp["per_step"]["gamma"].to_numpy()
    low = (gamma > 1.0) & (gamma < 1.0 / 0.7)
    assert np.all(np.isnan(shifted[0, low]))
    plain = repeat_check(cmp)
    robust = repeat_check(cmp, shifted=shifted)
    assert robust["model_periodic"] == plain["model_periodic"]
    assert robust["model_robust"] <= plain["model_periodic"] - np.count_nonzero(low)
    # the pseudo-data repeat where the model does (its own flights): nothing to name
    assert repeat_reason(robust) is None


def test_the_random_force_rule_is_offered_only_where_the_data_repeat_nowhere(tmp_path):
    """``random_force_rule``: None on the pseudo-data (the ideal ball's own flights, 0.005
    rad of timing noise: they repeat at every periodic step); with 1 rad of noise they
    repeat at no step within 2.5 samples of the placeholder recording (0.236 rad at 2 kHz),
    and the rule it returns names the ideal model's periodic steps."""
    run_dir = write_run(tmp_path)
    run = load_run(run_dir)
    clean = make_problem(run, pseudo_flights(run_dir, IDEAL, seed=7), duration_s(), n_members=2)
    assert random_force_rule(clean) is None
    noisy_flights = pseudo_flights(run_dir, IDEAL, seed=7, noise_rad=1.0)
    noisy = make_problem(run, noisy_flights, duration_s(), n_members=2)
    rule = random_force_rule(noisy)
    assert rule is not None
    assert "the flights do not repeat" in rule(IDEAL)
