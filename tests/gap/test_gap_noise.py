"""The noise floor (bouncelab.gap.noise): calibrated under the null, 1/sqrt(n) scaling."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from gap_synth import periodic_table, random_table

from bouncelab.gap import gap_table, noise_floor, overall_gap, overall_relative_gap, relative_gap
from bouncelab.gap.noise import block_labels, fill_scales, floor_from_scales, noise_scale


def _null_relative_gap(n, seed, **kw):
    data = random_table(n_steps=60, n=n, seed=seed)
    sim = random_table(n_steps=60, n=n, seed=seed + 1000)
    floor = noise_floor(data, sim, **kw)
    return relative_gap(gap_table(data, sim), floor)


@pytest.mark.parametrize("n", [50, 200])
def test_floor_is_calibrated_when_nothing_differs(n):
    """Data and simulation from the same distribution: the overall gap equals the floor
    up to sampling noise. Reference: the floor's definition (expected distance of two
    same-process samples). Tolerance: ratio within [0.8, 1.25], about 4 standard errors
    of the mean over 60 steps (the per-step ratio scatters by ~40 %)."""
    g = _null_relative_gap(n, seed=n)
    assert 0.8 < overall_relative_gap(g) < 1.25


def test_floor_shrinks_like_one_over_sqrt_n():
    """Quadrupling the flights per step halves the floor (W1 of two samples of one
    distribution ~ 1/sqrt(n)). Reference ratio 2; tolerance 15 % (the mean over 60
    steps of a per-step estimate that scatters by ~40 %)."""
    floors = []
    for n in (50, 200, 800):
        data = random_table(n_steps=60, n=n, seed=n)
        floors.append(overall_gap(noise_floor(data), "floor"))
    assert floors[0] / floors[1] == pytest.approx(2.0, rel=0.15)
    assert floors[1] / floors[2] == pytest.approx(2.0, rel=0.15)
    assert floors[2] < 0.05  # small: 800 flights of spread 0.3 rad


def test_floor_from_simulation_ensemble_members_and_from_another_seed():
    """A simulation with several ``start`` members is split even/odd; a second seed is
    used as given; either way the null ratio is about 1 (tolerance as above)."""
    data = random_table(n_steps=60, n=200, seed=1)
    sim_a = random_table(n_steps=60, n=100, seed=2).assign(start=0)
    sim_b = random_table(n_steps=60, n=100, seed=3).assign(start=1)
    sim = pd.concat([sim_a, sim_b], ignore_index=True)
    for compared, floor in (
        (sim, noise_floor(data, sim)),
        (sim_a, noise_floor(data, sim_a, sim_alt=sim_b)),
    ):
        g = relative_gap(gap_table(data, compared), floor)
        assert 0.8 < overall_relative_gap(g) < 1.25


def test_a_real_shift_stands_far_above_the_floor():
    """A shift of all flight times by 0.3 rad (one spread) with 200 flights per step:
    expected gap 0.3 against a floor of ~0.03-0.04, so gap/floor > 5."""
    data = random_table(n_steps=30, n=200, seed=1)
    sim = random_table(n_steps=30, n=200, seed=2, shift=0.3)
    g = relative_gap(gap_table(data, sim), noise_floor(data, sim))
    assert overall_relative_gap(g) > 5
    assert overall_gap(g, "w1_T") == pytest.approx(0.3, abs=0.05)


def test_periodic_data_has_a_floor_at_the_timing_noise_not_the_orbit():
    """A period-2 orbit (T = 2 and 4 rad) with 0.005 rad timing noise: halves in time
    hold both flights, so the floor stays near the noise (< 0.01 rad), far below the
    orbit's separation of 2 rad."""
    data = periodic_table([[2.0, 4.0]] * 10, np.linspace(3.8, 4.7, 10), noise=0.005, n=100)
    floor = noise_floor(data)
    assert floor["floor"].max() < 0.01


def test_block_labels_first_second_half_and_blocks():
    """Hand-checkable labels: settled flights ranked in time per step."""
    table = periodic_table([[1.0], [2.0]], [2.0, 3.0], n=10, unsettled=2)
    halves = block_labels(table, None)
    np.testing.assert_array_equal(halves[:10], [-1, -1, 0, 0, 0, 0, 1, 1, 1, 1])
    blocks = block_labels(table, 3)
    np.testing.assert_array_equal(blocks[10:], [-1, -1, 0, 0, 0, 1, 1, 1, 2, 2])


def test_scale_helpers():
    """s = d / sqrt(1/na + 1/nb); both empty -> 0, one empty -> NaN, filled from the
    other side then the median; floor = sqrt(sa^2/na + sb^2/nb) (definitions)."""
    s = noise_scale(np.array([0.2, 0.0, 1.0]), np.array([4, 0, 3]), np.array([4, 0, 0]))
    np.testing.assert_allclose(s[:2], [0.2 / np.sqrt(0.5), 0.0])
    assert np.isnan(s[2])
    np.testing.assert_allclose(fill_scales(s, np.array([1.0, 1.0, 0.7])), [s[0], 0.0, 0.7])
    np.testing.assert_allclose(fill_scales(s, np.full(3, np.nan))[2], np.median(s[:2]))
    f = floor_from_scales(np.array([2.0, 2.0]), np.array([4, 0]), np.array([3.0, 3.0]), [9, 9])
    np.testing.assert_allclose(f, [np.sqrt(1.0 + 1.0), 1.0])


def test_stuck_steps_have_zero_floor_and_min_floor_in_the_ratio():
    """Both sides stuck in a step: gap 0, floor 0, rel_gap 0 (min_floor avoids 0/0)."""
    data = periodic_table([[3.0], []], [2.0, 3.0])
    steps = pd.DataFrame({"step": [0, 1], "gamma": [2.0, 3.0]})
    g = relative_gap(gap_table(data, data, steps=steps), noise_floor(data, steps=steps))
    assert g.loc[1, "floor"] == 0.0 and g.loc[1, "rel_gap"] == 0.0
    assert g.loc[1, "floor_used"] == pytest.approx(0.01)


def test_null_relative_gaps_of_replicates_scatter_around_one():
    """Replicates of one process against each other: each ratio within [0.75, 1.33]
    (sampling scatter of a mean over 40 steps; the calibration test above)."""
    from bouncelab.gap import null_relative_gaps

    reps = [random_table(n_steps=40, n=100, seed=s) for s in range(3)]
    ratios = null_relative_gaps(reps)
    assert ratios.shape == (3,)
    assert np.all((ratios > 0.75) & (ratios < 1.33))
