"""Distances per Gamma step (bouncelab.gap.distances) against analytic values and scipy."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from gap_synth import periodic_table, random_table, step_frame
from scipy.stats import wasserstein_distance

from bouncelab.errors import BouncelabError
from bouncelab.gap import (
    gap_table,
    overall_gap,
    prepare_flights,
    projection_directions,
    return_map_pairs,
    sliced_wasserstein_2d,
    step_weights,
    wasserstein_1d,
)
from bouncelab.gap.distances import returnmap_scale

# Exact identities hold to rounding: the sort key rounds values to ~1e-10 rad.
EXACT = 1e-9


def test_distance_of_a_sample_to_itself_is_zero():
    """W1(x, x) = 0 and SW(p, p) = 0 (metric axiom); tolerance: rounding."""
    rng = np.random.default_rng(1)
    x = rng.gamma(2.0, 1.5, 500)
    assert wasserstein_1d(x, x) == pytest.approx(0.0, abs=EXACT)
    p = rng.normal(3.0, 1.0, (300, 2))
    assert sliced_wasserstein_2d(p, p) == pytest.approx(0.0, abs=EXACT)


def test_gap_table_of_a_table_with_itself_is_zero():
    """Every distance of a table to itself is 0 in every step (tolerance: rounding)."""
    table = periodic_table([[3.0], [2.0, 4.0], [1.0, 2.0, 3.0, 4.0]], [2.0, 3.0, 4.0])
    g = gap_table(table, table)
    assert np.all(np.abs(g[["w1_T", "w_returnmap", "gap"]].to_numpy()) < EXACT)


@pytest.mark.parametrize(
    ("a", "b", "n", "m"), [(0.0, 2.5, 1, 1), (1.0, 7.0, 5, 3), (4.0, 4.5, 10, 1)]
)
def test_w1_of_point_masses_is_their_separation(a, b, n, m):
    """W1(delta_a, delta_b) = |a - b| whatever the sample sizes (analytic)."""
    assert wasserstein_1d(np.full(n, a), np.full(m, b)) == pytest.approx(abs(a - b), abs=EXACT)


@pytest.mark.parametrize("shift", [0.0, 0.01, 0.7, 3.0])
def test_w1_of_a_shifted_sample_is_the_shift(shift):
    """W1(x, x + d) = |d| for any sample x in 1-D (analytic; tolerance: rounding)."""
    x = np.random.default_rng(2).exponential(2.0, 257)
    assert wasserstein_1d(x, x + shift) == pytest.approx(shift, abs=EXACT)
    assert wasserstein_1d(x + shift, x) == pytest.approx(shift, abs=EXACT)


@pytest.mark.parametrize(("n", "m"), [(1, 1), (7, 3), (100, 37), (1000, 999)])
def test_w1_matches_scipy(n, m):
    """Reference: scipy.stats.wasserstein_distance; tolerance 1e-9 rad (rounding)."""
    rng = np.random.default_rng(n + m)
    a, b = rng.gamma(2.0, 1.0, n), rng.normal(2.0, 1.0, m) ** 2
    assert wasserstein_1d(a, b) == pytest.approx(wasserstein_distance(a, b), abs=EXACT)


def test_stuck_side_is_a_point_mass_at_zero():
    """Convention (docs/gap.md): no flights = point mass at T = 0, so W1 = mean(T) of the
    other side (T >= 0); both sides stuck: 0."""
    x = np.array([0.5, 1.0, 4.0])
    assert wasserstein_1d(x, []) == pytest.approx(x.mean(), abs=EXACT)
    assert wasserstein_1d([], x) == pytest.approx(x.mean(), abs=EXACT)
    assert wasserstein_1d([], []) == 0.0


def test_sliced_distance_of_a_uniform_shift_is_the_shift():
    """Shifting every flight by d moves each pair by (d, d); the scale makes SW = d
    exactly (analytic, by construction of returnmap_scale)."""
    p = np.random.default_rng(3).uniform(0.0, 12.0, (200, 2))
    for d in (0.1, 1.0, 2.5):
        assert sliced_wasserstein_2d(p, p + d) == pytest.approx(d, abs=EXACT)


@pytest.mark.parametrize("k", [1, 4, 9])
def test_sliced_distance_matches_projected_scipy(k):
    """Reference: mean over the fixed directions of scipy's W1 of the projections, times
    the normalisation; tolerance 1e-9."""
    rng = np.random.default_rng(k)
    p, q = rng.normal(0.0, 1.0, (50, 2)), rng.normal(0.5, 2.0, (31, 2))
    dirs = projection_directions(k)
    ref = np.mean([wasserstein_distance(p @ d, q @ d) for d in dirs]) * returnmap_scale(dirs)
    assert sliced_wasserstein_2d(p, q, k) == pytest.approx(ref, abs=EXACT)


def test_directions_are_fixed_and_off_axis():
    """Deterministic unit vectors, none on an axis (the axes repeat the T marginal)."""
    dirs = projection_directions(4)
    np.testing.assert_array_equal(dirs, projection_directions(4))
    np.testing.assert_allclose(np.hypot(dirs[:, 0], dirs[:, 1]), 1.0)
    assert np.all(np.abs(dirs) > 0.1)


def test_return_map_tells_period_two_from_a_random_mixture():
    """Same flight-time marginal (w1_T = 0 exactly by construction), different order:
    a period-2 orbit against random draws of the same two values; only the return-map
    distance sees it (must exceed 10 x the rounding-level w1_T and be > 0.1 rad)."""
    rng = np.random.default_rng(4)
    n = 400
    period2 = np.resize([2.0, 4.0], n)
    mixture = rng.permutation(period2)  # the same values, order shuffled
    a = step_frame(0, 3.0, period2)
    b = step_frame(0, 3.0, mixture)
    g = gap_table(a, b)
    assert g["w1_T"].iloc[0] == pytest.approx(0.0, abs=EXACT)
    assert g["w_returnmap"].iloc[0] > 0.1


def test_gap_table_per_step_matches_scipy_with_settled_filter_and_stuck_steps():
    """Per step, w1_T equals scipy's W1 of the settled flights; a step where only one
    side flies gets mean(T) (point-mass convention); a step given in ``steps`` where
    neither flies gets 0; gap = (w1_T + w_returnmap) / 2 with the default alpha."""
    data = periodic_table([[3.0], [2.0, 4.0], [5.0], []], [2.0, 3.0, 4.0, 5.0], unsettled=5)
    sim = periodic_table([[3.2], [2.5, 4.0], [], []], [2.0, 3.0, 4.0, 5.0], seed=9)
    steps = pd.DataFrame({"step": [0, 1, 2, 3, 4], "gamma": [2.0, 3.0, 4.0, 5.0, 6.0]})
    g = gap_table(data, sim, steps=steps)
    assert list(g["step"]) == [0, 1, 2, 3, 4]
    for k in (0, 1):
        a = data.loc[(data.step == k) & data.settled, "T"]
        b = sim.loc[(sim.step == k) & sim.settled, "T"]
        assert g["w1_T"].iloc[k] == pytest.approx(wasserstein_distance(a, b), abs=EXACT)
        assert g["n_data"].iloc[k] == len(a)
    a2 = data.loc[(data.step == 2) & data.settled, "T"]
    assert g["w1_T"].iloc[2] == pytest.approx(a2.mean(), abs=EXACT)
    assert g["n_sim"].iloc[2] == 0
    assert g["gap"].iloc[3] == 0.0 and g["gap"].iloc[4] == 0.0
    np.testing.assert_allclose(g["gap"], 0.5 * (g["w1_T"] + g["w_returnmap"]))


def test_row_order_does_not_matter_when_a_time_column_is_present():
    """The table is put in time order first: shuffling rows leaves every distance."""
    data = periodic_table([[3.0], [2.0, 4.0], [1.0, 2.0, 3.0, 4.0]], [2.0, 3.0, 4.0])
    sim = periodic_table([[3.1], [2.0, 4.2], [1.0, 2.5, 3.0, 4.0]], [2.0, 3.0, 4.0], seed=5)
    shuffled = sim.sample(frac=1.0, random_state=0)
    pd.testing.assert_frame_equal(gap_table(data, sim), gap_table(data, shuffled))


def test_prepared_data_gives_the_same_table():
    data, sim = random_table(n_steps=5, seed=1), random_table(n_steps=5, seed=2)
    pd.testing.assert_frame_equal(gap_table(data, sim), gap_table(prepare_flights(data), sim))


def test_return_map_pairs_only_join_consecutive_settled_flights_of_one_member():
    """Hand-built table: pairs break at step changes, start changes and unsettled flights."""
    table = pd.DataFrame(
        {
            "step": [0, 0, 0, 1, 1, 1, 1],
            "gamma": [2.0, 2.0, 2.0, 3.0, 3.0, 3.0, 3.0],
            "T": [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0],
            "settled": [False, True, True, True, True, True, True],
            "start": [0, 0, 0, 0, 0, 1, 1],
            "t_takeoff": [0.0, 1.0, 2.0, 3.0, 4.0, 0.5, 1.5],
        }
    )
    pairs = return_map_pairs(table)
    got = sorted(zip(pairs["step"], pairs["T_n"], pairs["T_next"], strict=True))
    assert got == [(0, 2.0, 3.0), (1, 4.0, 5.0), (1, 6.0, 7.0)]


def test_overall_gap_weights():
    """Equal weights: plain mean over steps. Gamma weights: half the distance to each
    neighbour, so on the grid 1, 2, 4 the weights are 0.5, 1.5, 1 (/3) (hand computed)."""
    table = pd.DataFrame({"gamma": [1.0, 2.0, 4.0], "gap": [3.0, 6.0, 9.0]})
    assert overall_gap(table) == pytest.approx(6.0)
    np.testing.assert_allclose(step_weights(table, "gamma"), [0.5 / 3, 1.5 / 3, 1.0 / 3])
    assert overall_gap(table, weights="gamma") == pytest.approx((1.5 + 9.0 + 9.0) / 3)
    table.loc[1, "gap"] = np.nan  # NaN steps are left out
    assert overall_gap(table) == pytest.approx(6.0)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda t: t.drop(columns="T"), "lacks column 'T'"),
        (lambda t: t.assign(T=-t["T"]), "not >= 0"),
        (lambda t: t.assign(T=np.nan), "not >= 0"),
        (lambda t: t.assign(run=np.arange(len(t)) % 2), "runs"),
    ],
)
def test_bad_tables_raise_one_bouncelab_error(change, message):
    table = random_table(n_steps=2, n=5)
    with pytest.raises(BouncelabError, match=message) as err:
        gap_table(change(table), table)
    assert "data flight table" in str(err.value)
    assert "\n" not in str(err.value)
