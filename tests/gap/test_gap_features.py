"""Named features (bouncelab.gap.features) on synthetic tables with planted properties."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from gap_synth import periodic_table, step_frame

from bouncelab.gap import compare_features, count_clusters, features
from bouncelab.gap.features import circular_mean, wrap_angle

TWO_PI = 2 * np.pi
GAMMAS = np.round(np.linspace(0.5, 5.0, 46), 6)  # steps of 0.1


def planted_levels(onset=1.2, flip2=2.5, flip4=3.3, lock=(4.0, 4.5)):
    """Flight-time levels per step: stuck below ``onset``, period 1, 2, 4, then locked
    at T = 2 pi from ``lock[0]`` to ``lock[1]``, then a broad (chaotic) band."""
    levels = []
    for g in GAMMAS:
        if g < onset:
            levels.append([])
        elif g < flip2:
            levels.append([1.0 + g])
        elif g < flip4:
            levels.append([2.0 + g, 1.0 + g])
        elif g < lock[0]:
            levels.append([2.0 + g, 1.0, 3.0 + g, 0.5 + g])
        elif g <= lock[1]:
            levels.append([TWO_PI])
        else:
            levels.append(list(np.linspace(1.0, 9.0, 80)))  # a band of 80 even levels
    return levels


def planted_table(seed=0, **kw):
    return periodic_table(planted_levels(**kw), GAMMAS, n=80, noise=0.005, seed=seed)


def steps_frame():
    return pd.DataFrame({"step": np.arange(len(GAMMAS)), "gamma": GAMMAS})


@pytest.mark.parametrize(("levels", "expected"), [([3.0], 1), ([2.0, 4.0], 2), ([1, 2, 3, 4.5], 4)])
def test_count_clusters_of_periodic_orbits(levels, expected):
    """A period-n orbit with 0.01 rad timing noise gives n clusters (reference: planted)."""
    rng = np.random.default_rng(len(levels))
    t = np.resize(levels, 100) + rng.normal(0, 0.01, 100)
    assert count_clusters(t)[0] == expected


def test_count_clusters_of_a_band_and_of_strays():
    """A uniform band (chaos) is one cluster; a single stray flight is dropped (below
    min_share), an exactly periodic sample (all spacings 0) still splits by cluster_tol."""
    rng = np.random.default_rng(0)
    assert count_clusters(rng.uniform(1.0, 8.0, 100))[0] == 1
    t = np.concatenate([np.resize([2.0, 4.0], 99), [7.0]])
    assert count_clusters(t)[0] == 2
    assert count_clusters(np.resize([2.0, 4.0], 50))[0] == 2
    assert count_clusters([]) == (0, pytest.approx(np.nan, nan_ok=True))


def test_features_recover_planted_onset_doublings_and_plateau():
    """Planted: onset at Gamma 1.2, period 2 from 2.5, period 4 from 3.3, locked at 2 pi
    from 4.0 to 4.5 (exact step Gammas: the grid holds them)."""
    f = features(planted_table(), steps=steps_frame())
    assert f["takeoff_onset"] == pytest.approx(1.2)
    assert f["first_doubling"][2] == pytest.approx(2.5)
    assert f["first_doubling"][4] == pytest.approx(3.3)
    assert [(d["from"], d["to"]) for d in f["doublings"]] == [(1, 2), (2, 4)]
    assert len(f["plateaus"]) == 1
    p = f["plateaus"][0]
    assert (p["n"], p["gamma_min"], p["gamma_max"]) == (1, pytest.approx(4.0), pytest.approx(4.5))
    per = f["per_step"]
    assert (per.loc[per.gamma < 1.2, "n"] == 0).all()
    assert (per.loc[per.gamma > 4.55, "n_clusters"] == 1).all()  # the band
    assert (per.loc[per.gamma > 4.55, "spread"] > 1.0).all()  # ... and it is broad


def test_chatter_share_planted():
    """Every 5th flight replaced by a 0.02 rad flight: share 0.2 exactly (planted); a step
    of only short flights near onset (0.05 rad each) is not chatter (relative rule)."""
    T = np.resize([3.0, 3.0, 3.0, 3.0, 0.02], 100)
    table = pd.concat([step_frame(0, 2.0, T), step_frame(1, 1.01, np.full(50, 0.05))])
    per = features(table)["per_step"]
    assert per["chatter_share"].tolist() == [pytest.approx(0.2), 0.0]
    assert per["n_clusters"].iloc[0] == 1  # chatter left out of the cluster count
    flagged = features(table.assign(chatter=table["T"] < 0.03), opts=_opts(True))
    assert flagged["chatter_share"] == pytest.approx(20 / 150)


def _opts(use_column):
    from bouncelab.gap import FeatureOptions

    return FeatureOptions(use_chatter_column=use_column)


def test_phase_offset_planted():
    """Takeoff phases planted at 1.0 and 1.3 rad (noise 0.02 rad, 80 flights per step):
    offset 0.3 rad within 0.02 (5 standard errors of a circular mean)."""
    data = periodic_table([[3.0]] * 5, GAMMAS[:5] + 2, phase=1.0)
    sim = periodic_table([[3.0]] * 5, GAMMAS[:5] + 2, phase=1.3, seed=1)
    cmp = compare_features(data, sim)
    assert cmp["phase_offset"]["mean"] == pytest.approx(0.3, abs=0.02)
    assert "phase_offset" in cmp["differing"]
    assert cmp["per_step"]["differs_phase"].all()


def test_compare_features_names_the_planted_differences_and_nothing_else():
    """Simulation with onset 1.0 instead of 1.2 and the first doubling at 2.8 instead
    of 2.5; everything else alike. Same table against itself: nothing differs."""
    data = planted_table(seed=0)
    same = compare_features(data, planted_table(seed=1), steps=steps_frame())
    assert same["differing"] == []
    sim = planted_table(seed=1, onset=1.0, flip2=2.8)
    cmp = compare_features(data, sim, steps=steps_frame())
    assert cmp["differing"] == ["doubling_2", "takeoff_onset"]
    assert cmp["takeoff_onset"]["diff"] == pytest.approx(-0.2)
    assert cmp["doubling_2"]["diff"] == pytest.approx(0.3)
    per = cmp["per_step"]
    assert per.loc[per.differs_sticking, "gamma"].tolist() == pytest.approx([1.0, 1.1])
    assert per.loc[per.differs_clusters, "gamma"].tolist() == pytest.approx([2.5, 2.6, 2.7])


def test_circular_helpers():
    """Circular mean across the 0/2 pi cut, and wrapping into (-pi, pi] (analytic)."""
    mean, r = circular_mean(np.array([0.1, 2 * np.pi - 0.1]))
    assert mean == pytest.approx(0.0, abs=1e-12) and r == pytest.approx(np.cos(0.1))
    np.testing.assert_allclose(
        wrap_angle(np.array([3 * np.pi / 2, -3.5, np.pi])), [-np.pi / 2, 2 * np.pi - 3.5, np.pi]
    )


def test_one_grid_step_of_disagreement_is_not_a_difference():
    """Onset 1.1 against 1.2 on a grid of 0.1: within the default tolerance of 1.5 grid
    steps, so not named; with gamma_tol = 0 it is."""
    from bouncelab.gap import FeatureOptions

    data, sim = planted_table(seed=0), planted_table(seed=1, onset=1.1)
    assert compare_features(data, sim, steps=steps_frame())["differing"] == []
    strict = compare_features(data, sim, steps=steps_frame(), opts=FeatureOptions(gamma_tol=0.0))
    assert strict["differing"] == ["takeoff_onset"]
