"""Regions of the gap over Gamma (bouncelab.gap.regions): planted change points."""

from __future__ import annotations

import itertools

import numpy as np
import pandas as pd
import pytest

from bouncelab.gap import segment_profile, segment_regions
from bouncelab.gap.regions import default_penalty, robust_noise


def planted_profile(seed=0):
    """Relative gap over 60 steps: 1 (steps 0-19), 8 (20-34), 2.5 (35-59), each with a
    25 % multiplicative scatter, like gap / floor of a fitted model."""
    rng = np.random.default_rng(seed)
    level = np.concatenate([np.full(20, 1.0), np.full(15, 8.0), np.full(25, 2.5)])
    return level * np.exp(rng.normal(0.0, 0.25, level.size))


def _brute_force(y, min_size, beta):
    """Reference: the cheapest of all partitions with segments >= min_size."""
    n = len(y)
    best, best_cut = np.inf, None
    for k in range(n):
        for cuts in itertools.combinations(range(1, n), k):
            bounds = [0, *cuts, n]
            if min(np.diff(bounds)) < min_size:
                continue
            cost = sum(
                np.sum((y[a:b] - y[a:b].mean()) ** 2) + beta for a, b in itertools.pairwise(bounds)
            )
            if cost < best - 1e-12:
                best, best_cut = cost, list(itertools.pairwise(bounds))
    return best_cut


@pytest.mark.parametrize("seed", range(5))
def test_segmentation_is_the_exact_optimum(seed):
    """Reference: exhaustive search over all partitions of 9 values (min size 2)."""
    y = np.random.default_rng(seed).normal(0.0, 1.0, 9)
    y[5:] += 3.0
    assert segment_profile(y, min_size=2, penalty=1.0) == _brute_force(y, 2, 1.0)


@pytest.mark.parametrize("seed", range(5))
def test_planted_change_points_are_recovered(seed):
    """Change points planted at steps 20 and 35 come back within one step."""
    cuts = segment_profile(np.log1p(planted_profile(seed)), min_size=3)
    assert len(cuts) == 3
    assert abs(cuts[1][0] - 20) <= 1 and abs(cuts[2][0] - 35) <= 1


def test_a_flat_profile_is_one_region_and_min_size_holds():
    """Pure noise (no change planted) stays one region; short profiles are one region."""
    y = np.random.default_rng(1).normal(1.0, 0.1, 80)
    assert segment_profile(y) == [(0, 80)]
    assert segment_profile(np.ones(5), min_size=3) == [(0, 5)]
    y = np.r_[np.zeros(10), 5.0, np.zeros(10)]  # a one-step spike cannot be a region
    assert all(b - a >= 3 for a, b in segment_profile(y, min_size=3))


def test_robust_noise_ignores_level_changes():
    """sigma of N(0, 0.2) noise with two big jumps: 0.2 within 20 % (sampling, 400 values)."""
    y = np.random.default_rng(2).normal(0.0, 0.2, 400) + np.repeat(
        [0.0, 10.0, 3.0], [150, 150, 100]
    )
    assert robust_noise(y) == pytest.approx(0.2, rel=0.2)
    assert default_penalty(y) == pytest.approx(3 * robust_noise(y) ** 2 * np.log(400))


def test_segment_regions_sizes_and_features():
    """Regions carry Gamma limits, mean gap, floor and ratio, and the features that differ
    in at least a third of their steps (planted: cluster counts differ in steps 20-34)."""
    rel = planted_profile(0)
    n = rel.size
    gamma = 1.0 + 0.1 * np.arange(n)
    table = pd.DataFrame(
        {"step": np.arange(n), "gamma": gamma, "gap": 0.05 * rel, "floor": np.full(n, 0.05)}
    )
    table["floor_used"] = table["floor"]
    table["rel_gap"] = rel
    per_step = pd.DataFrame({"step": np.arange(n), "gamma": gamma})
    for col in ("differs_sticking", "differs_locking", "differs_chatter", "differs_phase"):
        per_step[col] = False
    per_step["differs_clusters"] = (np.arange(n) >= 20) & (np.arange(n) < 35)
    none = {"data": None, "sim": None, "diff": None}
    cmp = {"per_step": per_step, "takeoff_onset": none, "doubling_4": none}
    cmp["doubling_2"] = {"data": 3.0, "sim": 3.5, "diff": 0.5}
    regions = segment_regions(table, cmp)
    assert [r["n_steps"] for r in regions] == [20, 15, 25]
    middle = regions[1]
    assert middle["gamma_min"] == pytest.approx(3.0) and middle["gamma_max"] == pytest.approx(4.4)
    assert middle["gap"] == pytest.approx(table["gap"].iloc[20:35].mean())
    assert middle["rel_gap"] == pytest.approx(middle["gap"] / 0.05)
    assert middle["features"] == ["clusters", "doubling_2"]
    assert regions[0]["features"] == [] and regions[2]["features"] == []
    assert all(r["explained_by"] is None for r in regions)


def test_a_smooth_ramp_is_not_cut_into_many_regions():
    """A noiseless gap growing from 10 to 30 floors over 40 steps: without a noise floor
    the penalty would vanish and every step could be a region; min_sigma = 0.15 keeps
    it to a few. Reference: a ramp of height H = ln(31/11) ~ 1.04 over L = 40 steps cut
    into k pieces costs ~ L H^2 / (12 k^2) + k * 3 * 0.15^2 ln 40, least at k ~ 3."""
    rel = np.linspace(10.0, 30.0, 40)
    table = pd.DataFrame(
        {"step": np.arange(40), "gamma": np.arange(40) * 0.1, "gap": rel, "rel_gap": rel}
    )
    assert 2 <= len(segment_regions(table)) <= 4
    assert len(segment_regions(table, min_sigma=0.0)) > 10
