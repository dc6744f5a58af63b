"""Limits that must reproduce a simpler model, and the still-plate drop test."""

import math

import numpy as np
import pytest

from bouncelab.physics import Model, simulate_drop, simulate_grid

IDEAL = Model.parse("ideal")
# periodic (non-chaotic) Gamma values: nearby models stay close flight after flight
GAMMAS = [1.3, 2.0, 2.6, 3.5]


def _t(model, gammas=GAMMAS, n=30, skip=0):
    return simulate_grid(model, gammas, n, n_skip=skip)["T"].to_numpy()


@pytest.mark.parametrize(
    ("name", "params"),
    [("restitution", {"e": 0.0}), ("harmonic", {"a": 0.0}), ("feedback", {"mass_ratio": 0.0})],
)
def test_zero_strength_is_ideal_exactly(name, params):
    # e = 0, a = 0, mass_ratio = 0 switch the effect off: bit-identical flight times
    assert np.array_equal(_t(Model.parse(name, params)), _t(IDEAL))


@pytest.mark.parametrize(
    ("name", "params", "tol"),
    [
        # e = 1e-6: rebounds of 1e-6 |u| end at once in the summed chatter tail (< 1e-5 rad)
        ("restitution", {"e": 1e-6}, 1e-5),
        # a = 1e-9 goes through the general (harmonic) ride and landing code: O(a) change
        ("harmonic", {"a": 1e-9, "k": 2.7, "psi": 1.0}, 1e-6),
        # mass_ratio = 1e-9: armature kicks of O(1e-9): O(1e-9) change
        ("feedback", {"mass_ratio": 1e-9, "f_ratio": 0.4, "zeta": 0.1}, 1e-6),
    ],
)
def test_weak_effect_approaches_ideal(name, params, tol):
    t = _t(Model.parse(name, params))
    assert np.max(np.abs(t - _t(IDEAL))) < tol


def test_gamma_scale_is_ideal_at_true_gamma():
    # s = 1.2: the plate runs at 1.2 x stated Gamma; rows carry the stated Gamma
    df = simulate_grid(Model.parse("gamma_scale", {"s": 1.2}), GAMMAS, 10)
    ref = simulate_grid(IDEAL, 1.2 * np.array(GAMMAS), 10)
    assert np.array_equal(df["T"].to_numpy(), ref["T"].to_numpy())
    assert np.allclose(np.unique(df["gamma"]), GAMMAS)


@pytest.mark.parametrize(("mu", "e", "h"), [(0.29, 0.515, 1.0), (0.1, 0.8, 0.3), (0.0, 0.5, 2.0)])
def test_drop_on_still_plate(mu, e, h):
    df = simulate_drop(Model.parse("friction+restitution", {"mu": mu, "e": e}), h)
    t = df["T"].to_numpy()
    # fall time sqrt(2 chi / (1 - mu)) (nondimensional sqrt(2h/(g(1-mu)))); tolerance 1e-12
    assert t[0] == pytest.approx(math.sqrt(2 * h / (1 - mu)), abs=1e-12)
    # successive flights shrink by e sqrt((1-mu)/(1+mu)); tolerance 1e-9 relative while
    # flights are long compared with the contact resolution
    ratio = t[2:] / t[1:-1]
    long = t[2:] > 1e-3
    assert np.allclose(ratio[long], e * math.sqrt((1 - mu) / (1 + mu)), rtol=1e-9, atol=0)
    # first rebound: up at e v_impact against 1 + mu, down against 1 - mu
    w = e * math.sqrt(2 * h * (1 - mu))
    t1 = w / (1 + mu) + w / math.sqrt((1 + mu) * (1 - mu))
    assert t[1] == pytest.approx(t1, rel=1e-12)
    # (the first rebound, up and down, may outlast the fall: chatter from the second on)
    assert df["chatter"].iloc[2:].all()


@pytest.mark.parametrize("e", [0.3, 0.515, 0.9, 0.95])
def test_drop_chatter_ends_at_analytic_time(e):
    # mu = 0: total time sqrt(2h) (1 + e)/(1 - e) (fall + geometric series of rebounds);
    # recorded flights + the summed tail must give it to 1e-9
    h = 1.0
    df = simulate_drop(Model.parse("restitution", {"e": e}), h, n_flights=100_000)
    total = df["T"].sum() + df["tail"].iloc[-1]
    assert total == pytest.approx(math.sqrt(2 * h) * (1 + e) / (1 - e), abs=1e-9)
    assert df["tail"].iloc[:-1].eq(0).all()
    # bounded work: the sequence ends after ~log(eps)/log(e) impacts
    assert len(df) < math.log(1e-5 / 10) / math.log(e) + 5


@pytest.mark.parametrize("mu", [0.2, 0.5])
def test_flights_are_continuous_across_the_friction_threshold(mu):
    """Just above Gamma = 1 + mu the body leaves a hair before the top of the plate's
    cycle; the event finder read a landing at once there (flights of 6e-17 rad from 1 ulp
    to 1e-11 above the threshold, 2.16 rad at the threshold itself for mu 0.2). The
    flight time is continuous in Gamma: reference, the threshold's own flight; 1e-9 rad
    within 1e-11 of it, 2e-3 rad 1e-6 above (the slope there, about 1e3 rad per unit)."""
    model = Model.parse("friction", {"mu": mu})
    at = _t(model, [1.0 + mu], n=5)
    assert np.all(at > 1.0)
    for rel in (2.3e-16, 1e-13, 1e-11):
        np.testing.assert_allclose(_t(model, [(1.0 + mu) * (1.0 + rel)], n=5), at, atol=1e-9)
    np.testing.assert_allclose(_t(model, [(1.0 + mu) * (1.0 + 1e-6)], n=5), at, atol=2e-3)
