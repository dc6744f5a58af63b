"""The repeat rule of the diagnosis (``gap.diagnose.repeat_reason``): data whose flights
repeat nowhere while the fitted model's repeat on periodic orbits are named unexplained
(a random force); data that repeat where the model does, or a model that never repeats,
are not.

Reference: synthetic period-1..3 tables (``gap_synth.periodic_table``) with planted
timing noise; the repeat of a noisy period-p step is ``median |e[n+p] - e[n]|``, the
median of the absolute difference of two independent N(0, s) draws, ``0.954 s``
(``sqrt(2) x 0.6745``)."""

from __future__ import annotations

import numpy as np
import pytest
from gap_synth import periodic_table

from bouncelab.gap import compare_features
from bouncelab.gap.diagnose import REPEAT_MIN_STEPS, REPEAT_TOL, repeat_check, repeat_reason
from bouncelab.gap.features import repeat_error

LEVELS = [[2.0], [3.1, 1.4], [2.2, 4.0, 0.9], [5.0], [2.6, 1.8]] * 2
GAMMAS = list(1.5 + 0.1 * np.arange(len(LEVELS)))


@pytest.mark.parametrize("period", [1, 2, 3, 8])
@pytest.mark.parametrize("noise", [0.0, 0.02])
def test_repeat_error_of_a_noisy_periodic_step(period, noise):
    """A period-p cycle (p up to 8) with timing noise s: 0.954 s, from 25 % below (the
    least of the eight periods' medians, each over about 400 pairs, reads low) to 5 %
    above; exactly 0 without noise (the least over periods finds p)."""
    rng = np.random.default_rng(period)
    cycle = rng.uniform(0.5, 6.0, period)
    t = np.resize(cycle, 400) + rng.normal(0.0, noise, 400)
    if noise == 0.0:
        assert repeat_error(t) == 0.0
    else:
        assert 0.75 * 0.954 * noise < repeat_error(t) < 1.05 * 0.954 * noise


def test_repeat_error_of_a_chaotic_band_and_of_too_few_flights():
    """Flight times drawn at random from 0.5-6 rad repeat at no period (median
    difference about 1.5 rad); fewer than 16 flights give NaN."""
    t = np.random.default_rng(1).uniform(0.5, 6.0, 300)
    assert repeat_error(t) > 1.0
    assert np.isnan(repeat_error(t[:15]))


def _check(data_noise, sim_noise, seed=0):
    data = periodic_table(LEVELS, GAMMAS, noise=data_noise, seed=seed)
    sim = periodic_table(LEVELS, GAMMAS, noise=sim_noise, seed=seed + 100)
    return repeat_check(compare_features(data, sim))


def test_data_scattered_about_the_model_s_periodic_orbits_are_unexplained():
    """Timing noise of 0.2 rad on the data (a random force: 1 ms at 30 Hz), none on the
    model: the model repeats at all 10 steps, the data at none."""
    check = _check(0.2, 0.0)
    assert check["model_periodic"] == len(LEVELS)
    assert check["data_least"] > REPEAT_TOL
    assert "the flights never repeat" in repeat_reason(check)


@pytest.mark.parametrize(
    "data_noise,sim_noise",
    [
        (0.002, 0.0),  # a rig's timing noise (10 us at 30 Hz): the data repeat too
        (0.2, 0.2),  # the model as scattered as the data: it repeats nowhere either
    ],
)
def test_no_reason_where_the_data_repeat_or_the_model_does_not(data_noise, sim_noise):
    assert repeat_reason(_check(data_noise, sim_noise)) is None


def test_too_few_periodic_steps_of_the_model_abstain():
    """Fewer than REPEAT_MIN_STEPS steps where the model repeats: no reason, however the
    data scatter."""
    check = {"model_periodic": REPEAT_MIN_STEPS - 1, "data_least": 1.0, "data_median": 1.0}
    assert repeat_reason(check) is None
    assert repeat_reason(check | {"model_periodic": REPEAT_MIN_STEPS}) is not None


def test_one_repeating_step_of_the_data_is_enough():
    """The data repeat at one step only (its noise 0.002 rad), scatter at the others."""
    data = periodic_table(LEVELS, GAMMAS, noise=0.2, seed=3)
    clean = periodic_table(LEVELS, GAMMAS, noise=0.002, seed=4)
    data.loc[data["step"] == 4, "T"] = clean.loc[clean["step"] == 4, "T"].to_numpy()
    sim = periodic_table(LEVELS, GAMMAS, noise=0.0, seed=5)
    check = repeat_check(compare_features(data, sim))
    assert check["data_least"] < REPEAT_TOL
    assert repeat_reason(check) is None
