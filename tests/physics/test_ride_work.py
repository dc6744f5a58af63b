"""Plate work during rides against independent quadrature of the normal force's power."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import quad

from bouncelab.physics import Model, simulate_grid, simulate_protocol


def test_ride_work_matches_quadrature():
    # friction + harmonic (k = 2.5, non-integer), e = 0: between a landing and the next
    # takeoff the body rides; the normal force N = p'' + 1 + mu sign(p') does work
    # int N p' dphi.  Reference: scipy quad in absolute phase, split at the plate's
    # turning points; e_plate minus the impact work (-u) p'(landing) must match to 1e-8.
    g, mu, k, a, psi = 2.2, 0.2, 2.5, 0.15, 0.7
    m = Model.parse("friction+harmonic", {"mu": mu, "k": k, "a": a, "psi": psi})
    df = simulate_protocol(m, [g], [60], settle_cycles=0)

    def p1(x):
        return g * (math.cos(x) + a * k * math.cos(k * x + psi))

    def p2(x):
        return -g * (math.sin(x) + a * k * k * math.sin(k * x + psi))

    def power(x):
        v = p1(x)
        return (p2(x) + 1 + (mu if v > 0 else -mu)) * v

    checked = 0
    for i in range(len(df) - 1):
        land = df["t_takeoff"].iloc[i] + df["T"].iloc[i]
        nxt = df["t_takeoff"].iloc[i + 1]
        if nxt - land < 1e-3:
            continue  # no ride to speak of
        xs = np.linspace(land, nxt, 4001)
        v = np.array([p1(x) for x in xs])
        cuts = xs[:-1][np.sign(v[:-1]) != np.sign(v[1:])]
        w = quad(power, land, nxt, points=list(cuts) or None, limit=200, epsabs=1e-12)[0]
        w_imp = -df["v_impact"].iloc[i] * p1(land)
        assert df["e_plate"].iloc[i] - w_imp == pytest.approx(w, abs=1e-8)
        checked += 1
    assert checked >= 20


@settings(max_examples=60, deadline=None)
@given(
    e=st.floats(0.0, 0.95),
    g=st.floats(0.95, 1.4),
    mu=st.floats(0.0, 0.6),
    a=st.floats(0.0, 0.3),
)
def test_chatter_always_ends(e, g, mu, a):
    # e near 1, Gamma near 1 (long chatter, grazing takeoffs): every run returns, with
    # each chatter sequence below the hard cap (bounded work, never a hang)
    m = Model.parse("friction+restitution+harmonic", {"e": e, "mu": mu, "a": a, "k": 0.7})
    df = simulate_grid(m, [g], 300, n_starts=2, seed=3)
    run = 0
    longest = 0
    for c in df["chatter"].to_numpy():
        run = run + 1 if c else 0
        longest = max(longest, run)
    assert longest < 10_000
    assert np.all(np.isfinite(df["T"])) and np.all(df["T"] >= 0)
