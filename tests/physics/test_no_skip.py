"""The landing solver never skips a contact: property test against dense brute force.

Random Gamma, takeoff phase, relative takeoff velocity, friction, harmonics (non-integer
k) and armature states; the relative height is sampled densely by an independent numpy
implementation of the plate and body motion.  A miss is a sample before the found
landing where the body is below the plate by more than the sampling can explain.
"""

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from physics_helpers import body_np

from bouncelab.physics import kernels as K

HTOL = 1e-13


def body_velocity_np(s, v0, mu):
    """Body velocity ``s`` after a takeoff with ``v0`` (two parabolas joined at the apex)."""
    if v0 > 0 and s < v0 / (1 + mu):
        return v0 - (1 + mu) * s
    return min(v0, 0.0) - (1 - mu) * (s - max(v0 / (1 + mu), 0.0))


def plate_np(phi, g, hk, ha, th, arm, lam, om, f2):
    """Plate position (numpy twin of kernels.plate_eval, written independently)."""
    p = g * np.sin(phi)
    for k, a, t in zip(hk, ha, th, strict=True):
        p = p + g * a * np.sin(k * phi + t)
    if arm is not None:
        y0, v0, aref = arm
        tau = phi - aref
        # y'' + 2 lam y' + f2 y = 0 solved with complex exponents r = -lam +- sqrt(-om)
        sq = np.sqrt(complex(-om))
        r1, r2 = -lam + sq, -lam - sq
        if abs(r1 - r2) < 1e-12:
            y = np.exp(-lam * tau) * (y0 + (v0 + lam * y0) * tau)
        else:
            c1 = (v0 - r2 * y0) / (r1 - r2)
            c2 = y0 - c1
            y = (c1 * np.exp(r1 * tau) + c2 * np.exp(r2 * tau)).real
        p = p + y
    return p


case = st.fixed_dictionaries(
    {
        "g": st.floats(0.0, 8.0),
        "phi0": st.floats(0.0, 2 * math.pi),
        # relative takeoff velocity; 0 = a takeoff from riding (often on the takeoff line)
        "w": st.one_of(st.just(0.0), st.floats(1e-6, 6.0)),
        "mu": st.one_of(st.just(0.0), st.floats(0.0, 0.6)),
        "harm": st.lists(
            st.tuples(st.floats(0.1, 6.0), st.floats(0.0, 0.5), st.floats(0.0, 2 * math.pi)),
            max_size=2,
        ),
        "arm": st.one_of(
            st.none(),
            st.tuples(
                st.floats(-0.3, 0.3),
                st.floats(-1.0, 1.0),
                st.floats(0.05, 3.0),
                st.floats(0.01, 1.0),
            ),
        ),
        "on_line": st.booleans(),
        # a predicted flight time: only a trial point, it must never change the landing;
        # absolute (0: none), or relative to the landing found without a guess (as the
        # previous flight's time is on a periodic orbit)
        "guess": st.one_of(st.just(0.0), st.floats(0.0, 30.0)),
        "guess_rel": st.one_of(st.none(), st.floats(-0.05, 0.05)),
    }
)


def check_case(c):
    g, mu = c["g"], c["mu"]
    hk = np.array([h[0] for h in c["harm"]], dtype=float)
    ha = np.array([h[1] for h in c["harm"]], dtype=float)
    th = np.array([h[2] for h in c["harm"]], dtype=float)
    gu, gd = 1 + mu, 1 - mu
    phi0 = c["phi0"]
    if c["on_line"] and not c["harm"] and c["arm"] is None and g > gu:
        phi0 = math.asin(gu / g)  # takeoff exactly on the takeoff line: h ~ s^3
    if c["arm"] is None:
        arm, lam, om, f2, f = False, 0.0, 0.0, 0.0, 1.0
        ay = av = 0.0
        armt = None
    else:
        ay, av, f, z = c["arm"]
        arm, lam, f2 = True, z * f, f * f
        om = f2 - lam * lam
        armt = (ay, av, 0.0)
    p, p1, p2, p3 = K.plate_eval(phi0, g, hk, ha, th, arm, ay, av, 0.0, lam, om, f2)
    if c["w"] == 0.0 and not K.takeoff_ok(p1, p2, gu, gd) and not c["on_line"]:
        return  # not a takeoff: a riding body stays on the plate here
    b0, b2, b3, b4 = K.arm_bounds(ay, av, f, lam) if arm else (0.0, 0.0, 0.0, 0.0)
    a0 = np.abs(ha).sum()
    m2 = gu + g * (1 + (np.abs(ha) * hk**2).sum()) + b2
    m3 = g * (1 + (np.abs(ha) * hk**3).sum()) + b3
    m4 = g * (1 + (np.abs(ha) * hk**4).sum()) + b4
    if m3 == 0.0:
        m3 = m4 = 1e-300  # still plate: the Taylor bounds are not needed
    x0, v0 = p, p1 + c["w"]

    def fly(guess):
        return K.fly(
            phi0, x0, v0, 1e6, g, gu, gd, hk, ha, th, arm, ay, av, 0.0, lam, om, f2,
            m2, m3, m4, g * (1 + a0) + b0, HTOL, 200_000, p, p1, p2, p3, guess,
        )  # fmt: skip

    s0 = fly(0.0)[0]
    guess = c["guess"] if c["guess_rel"] is None else s0 * (1.0 + c["guess_rel"])
    s, landed, nit, _, q1, *_ = fly(guess)
    assert landed and nit < 200_000
    # the guess changes how the landing is found, not which: equal to the landing's
    # conditioning.  Either run may stop at the first point within HTOL of the plate or
    # on the root itself (plus rounding of h), a distance of about HTOL / |h'|; for
    # micro-flights (|h'| ~ 1e-6) |h'| itself changes that much over it, hence 2x
    slope = abs(body_velocity_np(s, v0, mu) - q1)
    cond = 2.0 * (HTOL + 1e-15 * (1 + abs(x0) + abs(v0) * s + m2)) / max(slope, 1e-300)
    assert abs(s - s0) <= 1e-12 * s0 + cond, (c, s0, s, slope)
    # dense brute force up to the found landing (and a little beyond, to see it is real)
    n = 20_000
    ss = np.linspace(0.0, s, n + 1)[1:]
    ds = s / n
    h = body_np(ss, x0, v0, mu) - plate_np(phi0 + ss, g, hk, ha, th, armt, lam, om, f2)
    # between samples h can dip by at most m2 ds^2 / 8 below the chord; a miss is a
    # sample clearly below the plate before the landing
    slack = m2 * ds * ds + 1e-9
    before = ss < s - ds
    assert not np.any(h[before] < -slack), (c, s, float(h[before].min()))
    # and the landing is a real contact
    hs = body_np(np.array([s]), x0, v0, mu) - plate_np(
        np.array([phi0 + s]), g, hk, ha, th, armt, lam, om, f2
    )
    assert abs(hs[0]) < 1e-9


@settings(max_examples=1500, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(case)
def test_never_skips_a_landing(c):
    check_case(c)


def test_takeoff_exactly_on_the_line_grows_like_cube():
    # Gamma sin(phi0) = 1 exactly: h = G cos(phi0) s^3 / 6 + O(s^4); the solver must
    # neither land at once nor skip the real landing (reference: brentq-free check that
    # the flight equals the ideal flight time from the line, 0.56758 periods at 1.5)
    g = 1.5
    phi0 = math.asin(1 / g)
    e = np.zeros(0)
    p, p1, p2, p3 = K.plate_eval(phi0, g, e, e, e, False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    s, landed, *_ = K.fly(
        phi0, p, p1, 1e6, g, 1.0, 1.0, e, e, e, False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
        1 + g, g, g, g, HTOL, 200_000, p, p1, p2, p3, 0.0,
    )  # fmt: skip
    assert landed and abs(s / (2 * math.pi) - 0.56758) < 5e-6


def test_grazing_landing_is_found():
    # a body that just touches the plate tangentially: launch with the velocity that makes
    # the landing a double root (found by bisection on "lands before 2 pi"); the solver
    # must report a contact near the tangency, not fly on
    g, phi0 = 2.0, 0.7
    e = np.zeros(0)

    def first(w):
        p, p1, p2, p3 = K.plate_eval(phi0, g, e, e, e, False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        return K.fly(
            phi0, p, p1 + w, 1e6, g, 1.0, 1.0, e, e, e, False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
            1 + g, g, g, g, HTOL, 200_000, p, p1, p2, p3, 0.0,
        )[0]  # fmt: skip

    # flight time jumps where a graze appears; on both sides brute force must agree
    for w in np.linspace(0.5, 3.0, 200):
        s = first(w)
        ss = np.linspace(0, s, 40_001)[1:-1]
        p = g * np.sin(phi0)
        h = p + (g * np.cos(phi0) + w) * ss - ss**2 / 2 - g * np.sin(phi0 + ss)
        assert h.min() > -(1 + g) * (s / 40_000) ** 2


@pytest.mark.slow
@settings(max_examples=30_000, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(case)
def test_never_skips_a_landing_large(c):
    # the same property on 20x more cases (run with -m slow)
    check_case(c)
