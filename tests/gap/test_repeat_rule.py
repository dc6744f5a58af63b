"""The repeat rule of the diagnosis (``gap.diagnose.repeat_reason``): data whose flights
do not repeat where the fitted model's repeat on periodic orbits are named unexplained
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
from bouncelab.gap.diagnose import (
    REPEAT_DATA_SAMPLES,
    REPEAT_DATA_TOL,
    REPEAT_MIN_STEPS,
    REPEAT_TOL,
    no_repeat_warning,
    repeat_check,
    repeat_data_tol,
    repeat_reason,
)
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


def _check(data_noise, sim_noise, seed=0, sample_rad=0.0):
    data = periodic_table(LEVELS, GAMMAS, noise=data_noise, seed=seed)
    sim = periodic_table(LEVELS, GAMMAS, noise=sim_noise, seed=seed + 100)
    return repeat_check(compare_features(data, sim), sample_rad)


def test_data_scattered_about_the_model_s_periodic_orbits_are_unexplained():
    """Timing noise of 0.2 rad on the data (a random force: 1 ms at 30 Hz), none on the
    model: the model repeats at all 10 steps, the data at none."""
    check = _check(0.2, 0.0)
    assert check["model_periodic"] == len(LEVELS)
    assert check["data_median"] > REPEAT_DATA_TOL
    assert "the flights do not repeat" in repeat_reason(check)


def test_a_weak_random_force_is_named_too():
    """Timing noise of 0.03 rad (0.16 ms at 30 Hz; about 2 um of plate vibration in the
    independent generator): every step repeats within REPEAT_TOL, but the median repeat
    (0.954 x 0.03 = 0.029 rad) is over REPEAT_DATA_TOL."""
    check = _check(0.03, 0.0)
    assert check["data_least"] < REPEAT_TOL
    assert check["data_median"] > REPEAT_DATA_TOL
    assert repeat_reason(check) is not None


def test_a_raised_limit_silences_the_rule():
    """``SelectSettings.repeat_limit`` (``--repeat-limit``): the 0.03 rad scatter named at
    the default 0.02 rad is accepted under a limit of 0.05 (a lab that knows its rig
    scatters that much)."""
    data = periodic_table(LEVELS, GAMMAS, noise=0.03, seed=0)
    sim = periodic_table(LEVELS, GAMMAS, noise=0.0, seed=100)
    cmp = compare_features(data, sim)
    assert repeat_reason(repeat_check(cmp)) is not None
    raised = repeat_check(cmp, limit=0.05)
    assert raised["data_tol"] == 0.05 and repeat_reason(raised) is None


def test_the_limit_is_in_samples_of_a_coarse_recording():
    """A flight read off hard edges is whole samples long, so the limit is
    REPEAT_DATA_SAMPLES samples where they are longer than REPEAT_DATA_TOL: the same
    0.04 rad scatter is named at 44.1 kHz (a sample of 0.0043 rad at 30 Hz: the limit
    REPEAT_DATA_TOL) and at 20 kHz (0.0094 rad: 0.0236), not at 4 kHz (0.047: 0.118)."""
    checks = {fs: _check(0.04, 0.0, sample_rad=2 * np.pi * 30 / fs) for fs in (44100, 20000, 4000)}
    assert checks[44100]["data_tol"] == REPEAT_DATA_TOL
    assert checks[4000]["data_tol"] == pytest.approx(REPEAT_DATA_SAMPLES * 2 * np.pi * 30 / 4000)
    assert repeat_reason(checks[44100]) is not None
    assert repeat_reason(checks[20000]) is not None
    assert repeat_reason(checks[4000]) is None


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
    check = {
        "model_periodic": REPEAT_MIN_STEPS - 1,
        "data_least": 1.0,
        "data_median": 1.0,
        "data_tol": REPEAT_DATA_TOL,
    }
    assert repeat_reason(check) is None
    assert repeat_reason(check | {"model_periodic": REPEAT_MIN_STEPS}) is not None


@pytest.mark.parametrize("repeating,named", [(1, True), (4, True), (6, False)])
def test_the_median_over_the_model_s_periodic_steps_decides(repeating, named):
    """The data repeat (noise 0.002 rad) at some of the model's 10 periodic steps and
    scatter (0.2 rad) at the others: one or four repeating steps leave the median over
    the ten scattered, six bring it down (a model periodic where the data are not, at a
    minority of steps, is a fit's miss near a bifurcation, not a random force)."""
    data = periodic_table(LEVELS, GAMMAS, noise=0.2, seed=3)
    clean = periodic_table(LEVELS, GAMMAS, noise=0.002, seed=4)
    for step in range(repeating):
        data.loc[data["step"] == step, "T"] = clean.loc[clean["step"] == step, "T"].to_numpy()
    sim = periodic_table(LEVELS, GAMMAS, noise=0.0, seed=5)
    check = repeat_check(compare_features(data, sim))
    assert check["data_least"] < REPEAT_TOL
    assert (repeat_reason(check) is not None) == named


@pytest.mark.parametrize("robust,named", [(2, False), (3, True)])
def test_only_periodic_steps_that_a_shift_of_gamma_keeps_speak(robust, named):
    """A chaotic band where the fitted model sits in a periodic window: the model repeats
    at all 10 steps and the data scatter at all, but the shifted simulations
    (``shifted``) repeat at only ``robust`` of them (NaN: no flights there). Below
    REPEAT_MIN_STEPS such steps the rule abstains; ``model_periodic`` is unchanged."""
    data = periodic_table(LEVELS, GAMMAS, noise=0.2, seed=6)
    sim = periodic_table(LEVELS, GAMMAS, noise=0.0, seed=7)
    shifted = np.full((2, len(LEVELS)), 1.0)
    shifted[:, :robust] = 0.0
    shifted[1, robust] = np.nan  # one shift without flights: not periodic either
    check = repeat_check(compare_features(data, sim), shifted=shifted)
    assert check["model_periodic"] == len(LEVELS)
    assert check["model_robust"] == robust
    assert (repeat_reason(check) is not None) == named
    assert repeat_reason(repeat_check(compare_features(data, sim))) is not None


def test_an_explained_run_whose_flights_repeat_nowhere_is_warned_about():
    tol = repeat_data_tol(0.0094)
    # the data repeat at one step at least: silent, whatever the other steps do
    assert no_repeat_warning({"data_least": 0.004, "data_tol": tol}) is None
    assert no_repeat_warning({"data_least": None, "data_tol": tol}) is None  # no step to read
    line = no_repeat_warning({"data_least": 0.145, "data_tol": tol})
    assert line is not None and "repeat at no step" in line and "0.145" in line
    # the edge counts as no repeat, as the random force's stop reads it
    assert no_repeat_warning({"data_least": tol, "data_tol": tol}) is not None
