"""Shared helpers of the physics tests."""

import math

import numpy as np

from bouncelab.physics import Model, simulate_from, simulate_grid

TWO_PI = 2.0 * math.pi


def bisect(pred, lo, hi, n=18):
    """Smallest x in [lo, hi] where pred turns True (pred False at lo, True at hi)."""
    for _ in range(n):
        mid = 0.5 * (lo + hi)
        if pred(mid):
            hi = mid
        else:
            lo = mid
    return 0.5 * (lo + hi)


def ideal_period_doubled(gamma, skip):
    """True when the ideal ball from rest alternates flight times after ``skip`` flights."""
    t = simulate_grid(Model.parse("ideal"), [gamma], 4, n_skip=skip)["T"].to_numpy()
    return abs(t[0] - t[1]) > 1e-7


def restitution_orbit_start(gamma, e):
    """Phase and velocity of the restitution period-1 orbit's takeoff (T = 2 pi).

    Ballistics over one period give takeoff velocity pi; the impact law then needs
    ``Gamma cos(phi*) = pi (1 - e) / (1 + e)`` (the stable branch has sin(phi*) > 0).
    """
    c = math.pi * (1 - e) / (1 + e) / gamma
    return math.acos(c), math.pi


def restitution_period_doubled(gamma, e, skip):
    # start 1e-6 off the orbit: exactly on it, the frame reduction reproduces the fixed
    # point bit for bit and an unstable orbit would never be left
    ph, v = restitution_orbit_start(gamma, e)
    ph += 1e-6
    m = Model.parse("restitution", {"e": e})
    t = simulate_from(m, gamma, ph, gamma * math.sin(ph), v, 4, n_skip=skip)["T"].to_numpy()
    return len(t) < 4 or abs(t[0] - t[1]) > 1e-7


def body_np(s, x0, v0, mu):
    """Body height (nondimensional) at times ``s`` after leaving ``x0`` with velocity ``v0``
    under Coulomb friction ``mu``: two parabolas joined at the apex (brute-force reference)."""
    gu, gd = 1 + mu, 1 - mu
    if v0 > 0:
        sa = v0 / gu
        xa = x0 + v0 * sa / 2
        return np.where(s < sa, x0 + v0 * s - gu * s * s / 2, xa - gd * (s - sa) ** 2 / 2)
    return x0 + v0 * s - gd * s * s / 2
