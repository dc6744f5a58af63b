"""numba kernels of the event-driven impact map (nondimensional units, see docs/physics.md).

Small compiled functions only; :mod:`bouncelab.physics.simulate` arranges them and
builds DataFrames.  Units: phase ``phi`` (rad), heights in ``g / omega^2``,
velocities in ``g / omega``, energies per unit body mass in ``(g / omega)^2``.

Model parameters travel in one float64 vector ``par`` (indices ``P_*``) plus three
arrays for the harmonics (``hk``, ``ha``, ``hpsi``, shape ``(n_harmonics,)``).  Output
rows are written into a float64 matrix ``out[column, row]`` with the column indices
``C_*``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

TWO_PI = 2.0 * math.pi
HALF_PI = 0.5 * math.pi

# --- parameter vector ``par`` -------------------------------------------------------
P_S = 0  # gamma_scale s: true Gamma = s * stated Gamma (applied by the caller)
P_MU = 1  # Coulomb friction, fraction of the weight
P_E = 2  # coefficient of restitution
P_R = 3  # mass_ratio: body mass / armature mass
P_F = 4  # f_ratio: armature natural frequency / drive frequency
P_Z = 5  # zeta: armature damping ratio
P_EPS = 6  # chatter threshold: a predicted flight shorter than this (rad) ends the chatter
P_HTOL = 7  # contact resolution: relative height <= HTOL counts as contact
P_CAP = 8  # hard cap on flights in one chatter sequence
P_RIDE = 9  # longest ride searched for a takeoff (rad) before declaring the body stuck
P_FAST = 10  # 1.0: pure sine plates use fly_sine; 0.0: the general solver fly everywhere
NPAR = 11

# --- output columns -----------------------------------------------------------------
C_GAMMA = 0  # stated Gamma at takeoff
C_T = 1  # flight time (rad)
C_PHI0 = 2  # takeoff phase in [0, 2 pi)
C_PHIL = 3  # landing phase in [0, 2 pi)
C_VIMP = 4  # relative velocity at landing (body - plate), <= 0
C_EFRIC = 5  # friction loss: flight + ride after it
C_EIMP = 6  # impact loss (landing impact, or the whole summed chatter tail)
C_EPLATE = 7  # work done by the plate on the body: impact + ride after it
C_CHAT = 8  # 1.0 for a rebound from the sticking region shorter than the flight before
C_START = 9  # ensemble member
C_STEP = 10  # protocol step of the takeoff
C_TTO = 11  # absolute takeoff phase since the start (rad)
C_SETTLED = 12  # 1.0 unless the takeoff is within settle cycles of its step start
C_X0 = 13  # body height at takeoff
C_V0 = 14  # body velocity at takeoff (lab frame)
C_FLIGHT = 15  # flight index in the trajectory (skipped transients included)
C_NSTEPS = 16  # solver iterations spent on this flight's landing (diagnostic)
C_TAIL = 17  # duration (rad) of the summed chatter tail after this flight's landing, else 0
NCOL = 18

# trajectory status codes
ST_DONE = 0  # recorded what was asked
ST_STUCK = 1  # the body can no longer take off (e.g. Gamma <= 1 for ideal)
ST_END = 2  # the protocol's last step ended
ST_FULL = 3  # the output buffer is full before the protocol ended


@njit(cache=True)
def safe_step(f, f1, m):
    """Largest ``t`` with ``f + f1 t - m t^2 / 2 > 0`` on ``[0, t)``, given ``f >= 0``, ``m > 0``.

    This is the certified step: if ``m`` bounds the second derivative of a function
    from above in magnitude, the function cannot reach zero before ``t``.  Near a
    transversal zero it equals a Newton step from the safe side (quadratic convergence).
    """
    disc = f1 * f1 + 2.0 * m * f
    if disc <= 0.0:
        return 0.0
    sq = math.sqrt(disc)
    if f1 >= 0.0:
        return (f1 + sq) / m
    # f1 < 0: the same root written without cancellation
    return 2.0 * f / (sq - f1)


@njit(cache=True)
def arm_eval(tau, y0, v0, lam, om, f2):
    """Armature deflection ``y`` and its first three phase derivatives ``tau`` after a reference.

    Solves ``y'' + 2 lam y' + f2 y = 0`` (``lam = zeta f``, ``f2 = f^2``,
    ``om = f2 - lam^2``) in closed form from ``y(0) = y0``, ``y'(0) = v0``; under-,
    critically and over-damped cases alike, written so that no term overflows.
    """
    b = v0 + lam * y0
    if om > 0.0:
        w = math.sqrt(om)
        ex = math.exp(-lam * tau)
        ec = ex * math.cos(w * tau)
        es = ex * math.sin(w * tau) / w
    elif om < 0.0:
        w = math.sqrt(-om)
        # e^{-lam t} cosh(w t) and e^{-lam t} sinh(w t)/w with w < lam: no overflow
        ep = math.exp((w - lam) * tau)
        em = math.exp(-(w + lam) * tau)
        ec = 0.5 * (ep + em)
        es = 0.5 * (ep - em) / w
    else:
        ex = math.exp(-lam * tau)
        ec = ex
        es = ex * tau
    y = y0 * ec + b * es
    y1 = -lam * y + (-om * y0 * es + b * ec)
    y2 = -2.0 * lam * y1 - f2 * y
    y3 = -2.0 * lam * y2 - f2 * y1
    return y, y1, y2, y3


@njit(cache=True)
def arm_bounds(y0, v0, f, lam):
    """Bounds on ``|y|, |y''|, |y'''|, |y''''|`` for all later phases (armature energy never grows).

    With ``S = sqrt(y'^2 + f^2 y^2)`` (non-increasing for ``zeta >= 0``):
    ``|y| <= S/f``, ``|y'| <= S``, ``|y''| <= (2 zeta + 1) f S`` and so on by the ODE.
    """
    s = math.sqrt(v0 * v0 + f * f * y0 * y0)
    b0 = s / f
    b1 = s
    b2 = 2.0 * lam * b1 + f * f * b0
    b3 = 2.0 * lam * b2 + f * f * b1
    b4 = 2.0 * lam * b3 + f * f * b2
    return b0, b2, b3, b4


@njit(cache=True)
def plate_eval(phi, g, hk, ha, th, arm, ay, av, aref, lam, om, f2):
    """Plate position and first three derivatives at phase ``phi``.

    ``chi_p = g [sin(phi) + sum_j a_j sin(k_j phi + th_j)] + y(phi - aref)`` where ``th_j``
    is harmonic j's phase offset in the current frame and ``y`` the armature deflection.
    """
    sn = math.sin(phi)
    cs = math.cos(phi)
    p = sn
    p1 = cs
    p2 = -sn
    p3 = -cs
    for j in range(hk.shape[0]):
        k = hk[j]
        arg = k * phi + th[j]
        sj = ha[j] * math.sin(arg)
        cj = ha[j] * math.cos(arg)
        p += sj
        p1 += k * cj
        p2 -= k * k * sj
        p3 -= k * k * k * cj
    p *= g
    p1 *= g
    p2 *= g
    p3 *= g
    if arm:
        y, y1, y2, y3 = arm_eval(phi - aref, ay, av, lam, om, f2)
        p += y
        p1 += y1
        p2 += y2
        p3 += y3
    return p, p1, p2, p3


@njit(cache=True)
def body_eval(s, x0, v0, gu, gd):
    """Body height, velocity and acceleration ``s`` after leaving ``(x0, v0)``.

    Coulomb friction on the guide: effective gravity ``gu = 1 + mu`` while moving up,
    ``gd = 1 - mu`` while moving down; two parabolas joined at the apex.
    """
    if v0 > 0.0:
        sa = v0 / gu
        if s < sa:
            return x0 + v0 * s - 0.5 * gu * s * s, v0 - gu * s, -gu
        xa = x0 + 0.5 * v0 * sa
        t = s - sa
        return xa - 0.5 * gd * t * t, -gd * t, -gd
    return x0 + v0 * s - 0.5 * gd * s * s, v0 - gd * s, -gd


@njit(cache=True)
def path_length(s, x0, v0, gu, gd):
    """Distance travelled by the body in its first ``s`` of flight (friction loss = mu * path)."""
    xs = body_eval(s, x0, v0, gu, gd)[0]
    if v0 > 0.0:
        sa = v0 / gu
        if s > sa:
            xa = x0 + 0.5 * v0 * sa
            return (xa - x0) + (xa - xs)
        return xs - x0
    return x0 - xs


@njit(cache=True)
def fly(
    phi0, x0, v0, smax, g, gu, gd, hk, ha, th, arm, ay, av, aref, lam, om, f2,
    m2, m3, m4, pmax, htol, maxit, q0, q1, q2, q3,
):  # fmt: skip
    """First contact after leaving ``(x0, v0)`` at phase ``phi0``.

    ``q0..q3``: the plate's position and first three derivatives at ``phi0`` (known to
    the caller from the takeoff).  Returns ``(s, landed, n_iter, p, p1, p2, p3)``: the
    flight time, whether it landed (False: reached ``smax``), the iterations, and the
    plate position and derivatives at the contact (zeros when not landed).

    ``h(s) = x_body(s) - chi_p(phi0 + s)`` is the relative height.  No-skip argument:
    every move from ``s`` to ``s + t`` is certified by a lower bound of ``h`` that stays
    positive on ``[s, s + t)``:

    - ``h + h' t - m2 t^2/2`` with ``m2 >= sup(-h'')`` (gravity + plate acceleration bound);
    - ``h + h' t + h'' t^2/2 - m3 t^3/6`` and the quartic analogue with ``m3 >= sup|p'''|``,
      ``m4 >= sup|p''''|``, used when the lower derivatives are >= 0 (a takeoff on or near
      the takeoff line, where ``h`` grows like ``s^3``); the only jump of ``h''`` is upward
      (at the apex friction flips sign), so these Taylor bounds stay valid;
    - ``x_body(s + t) > pmax >= max chi_p`` while the body is above the plate's range.

    The first ``s`` where ``h <= htol`` while ``h' <= 0`` is the contact (a graze counts
    when it comes within ``htol``).  Once ``h <= 1e-6`` with ``h' < -0.1`` (a clearly
    transversal approach) Newton steps finish: each overshoots the certified step by at
    most ``m2 h^2 / (2 |h'|^3) < 1e-9 m2``, far too short for a contact to hide in
    (its depth would be below ``m2 * 1e-18``).  If the flight reaches ``smax`` (a
    protocol step boundary) it stops there.
    """
    # the body's apex, once (friction: two parabolas joined there)
    if v0 > 0.0:
        sa = v0 / gu
        xa = x0 + 0.5 * v0 * sa
        va = 0.0
    else:
        sa = 0.0
        xa = x0
        va = v0
    # the time the body comes down through pmax (if it rises above it at all)
    s_desc = -1.0
    if xa > pmax:
        s_desc = sa + (va + math.sqrt(va * va + 2.0 * gd * (xa - pmax))) / gd
    s = 0.0
    p, p1, p2, p3 = q0, q1, q2, q3
    for it in range(maxit):
        if it > 0:
            p, p1, p2, p3 = plate_eval(phi0 + s, g, hk, ha, th, arm, ay, av, aref, lam, om, f2)
        if s < sa:
            xb = x0 + v0 * s - 0.5 * gu * s * s
            vb = v0 - gu * s
            ab = -gu
        else:
            ts = s - sa
            xb = xa + va * ts - 0.5 * gd * ts * ts
            vb = va - gd * ts
            ab = -gd
        h = xb - p
        h1 = vb - p1
        h2 = ab - p2
        if s == 0.0:
            # a takeoff: the body starts on the plate with the plate's velocity (plus
            # any rebound); the frame shift leaves rounding-sized h, h' (and h'' on the
            # takeoff line) that must not read as an immediate landing
            if abs(h) <= htol:
                h = 0.0
            if abs(h1) < 1e-12 * (1.0 + abs(v0)):
                h1 = 0.0
            if -1e-12 * m2 < h2 < 0.0:
                h2 = 0.0
        elif h <= 1e-6 and h1 < -0.1:
            # transversal approach: Newton finish (see docstring)
            for _ in range(4):
                dt = h / (-h1)
                s += dt
                p, p1, p2, p3 = plate_eval(phi0 + s, g, hk, ha, th, arm, ay, av, aref, lam, om, f2)
                if s < sa:
                    h = x0 + v0 * s - 0.5 * gu * s * s - p
                    h1 = v0 - gu * s - p1
                else:
                    ts = s - sa
                    h = xa + va * ts - 0.5 * gd * ts * ts - p
                    h1 = va - gd * ts - p1
                if abs(h) <= htol or abs(dt) < 1e-15 * (1.0 + s):
                    break
            return s, True, it, p, p1, p2, p3
        # contact: within htol of the plate and not moving away from it (a body just
        # above the plate but rising, e.g. after a tiny rebound, is still in flight)
        if h <= htol and h1 <= 0.0 and (s > 0.0 or h1 < 0.0 or h < -htol):
            if h1 < 0.0 and h > 0.0:
                dt = h / (-h1)
                if dt < 1e-7:
                    s += dt
                    # plate state carried along by Taylor (dt^3 terms are < 1e-21)
                    p += dt * (p1 + 0.5 * dt * p2)
                    p1 += dt * (p2 + 0.5 * dt * p3)
                    p2 += dt * p3
            return s, True, it, p, p1, p2, p3
        hh = max(h, 0.0)
        t = safe_step(hh, h1, m2)
        if h1 >= 0.0 and h2 >= 0.0 and h1 < 1e-2:
            # near a takeoff with small relative velocity the quadratic bound stalls; the
            # cubic bound holds while any one non-negative Taylor term beats m3 t^3/6
            t3 = 3.0 * h2 / m3
            if h1 > 0.0:
                t3 = max(t3, math.sqrt(6.0 * h1 / m3))
            if hh > 0.0:
                t3 = max(t3, (6.0 * hh / m3) ** (1.0 / 3.0))
            if t3 > t:
                t = t3
            h3 = -p3
            if h3 > 0.0:
                t4 = max(4.0 * h3 / m4, math.sqrt(12.0 * h2 / m4))
                if h1 > 0.0:
                    t4 = max(t4, (24.0 * h1 / m4) ** (1.0 / 3.0))
                if hh > 0.0:
                    t4 = max(t4, math.sqrt(math.sqrt(24.0 * hh / m4)))
                if t4 > t:
                    t = t4
        if xb > pmax and s_desc - s > t:
            t = s_desc - s  # above the plate's whole range until then
        if t <= 1e-14 * (1.0 + s):
            return s, True, it, p, p1, p2, p3  # stalled on a tangency: contact within rounding
        if s + t >= smax:
            return smax, False, it, 0.0, 0.0, 0.0, 0.0  # (plate not evaluated at smax)
        s += t
    p, p1, p2, p3 = plate_eval(phi0 + s, g, hk, ha, th, arm, ay, av, aref, lam, om, f2)
    return s, True, maxit, p, p1, p2, p3


# --- fast path: the pure sine plate -------------------------------------------------
# For ``chi_p = G sin(phi)`` (no harmonics, no armature) the curvature of the relative
# height is known in closed form, ``h'' = G sin(phi0 + s) - c`` with ``c = 1 + mu`` before
# the apex and ``1 - mu`` after it, so the flight splits into intervals where ``h`` is
# convex or concave, with edges at ``G sin(phi) = c``.  On each interval the exact
# function gives certificates that need no global derivative bound:
#
# - convex, ``h >= 0``, ``h' >= 0``: ``h`` increases, no contact up to the interval's end;
# - convex, ``h' < 0``: the tangent lies below ``h``, so ``h > 0`` up to the tangent's root
#   (a Newton step from the safe side, converging monotonically to the first root);
# - concave: ``h >= min(h(a), h(b))`` on ``[a, b]``, so one evaluation at ``b`` with
#   ``h(b) > 0`` clears the whole interval; with ``h(b) <= 0`` the interval holds exactly
#   one root (a concave function crosses zero downward once), found by any bracketed
#   method.  The tangent at a point with ``h' < 0`` lies above ``h``, so its root is a
#   point with ``h <= 0``: the first trial point of the bracket.
#
# The edges are placed ``SINE_EDGE`` rad early so that a takeoff exactly on the takeoff
# line (``h'' = 0`` at ``s = 0`` up to rounding) starts inside its convex interval.  In
# that sliver the wrong-signed curvature is at most ``G SINE_EDGE``, which moves any bound
# by at most ``G SINE_EDGE^2 * (interval length) < 1e-19 * 8 * 4 pi``, far below the
# contact tolerance ``htol = 1e-13``: no contact deeper than ``htol`` can be skipped.
SINE_EDGE = 1e-10


@njit(cache=True)
def sine_alpha(g, c):
    """Phase ``asin(c / g)`` where ``g sin(phi) = c`` on the rising side; ``-1`` if ``g <= c``."""
    if g <= c:
        return -1.0
    return math.asin(c / g)


@njit(cache=True)
def sine_region(phi, al):
    """Curvature interval of ``h'' = g sin(phi) - c`` holding ``phi``: ``(convex, end phase)``.

    ``al = asin(c / g)`` (``-1``: ``g <= c``, concave everywhere, end ``inf``).  Convex on
    ``[al, pi - al)`` modulo ``2 pi``, both edges moved ``SINE_EDGE`` earlier.  A phase
    within rounding (``1e-13 (1 + phi)``) of an edge belongs to the interval that starts
    there, so that a walk that has just reached an edge always moves on.
    """
    if al < 0.0:
        return False, math.inf
    a = al - SINE_EDGE
    n = math.floor((phi - a) / TWO_PI)
    r = phi - a - n * TWO_PI  # in [0, 2 pi): phase past the convex interval's start
    w = math.pi - 2.0 * al  # convex width
    tol = 1e-13 * (1.0 + abs(phi))
    if r < w - tol:
        return True, phi + (w - r)
    if r < TWO_PI - tol:
        return False, phi + (TWO_PI - r)
    return True, phi + (TWO_PI - r) + w  # at the end of a concave interval


@njit(cache=True)
def sine_h(s, phi0, x0, v0, sa, xa, va, gu, gd, g):
    """Relative height and its first two derivatives ``s`` after takeoff, pure sine plate.

    Body as in :func:`fly` (apex at ``sa``, height ``xa``, velocity ``va`` there: 0, or
    ``v0 <= 0`` with ``sa = 0``).  Returns ``(h, h', h'', sin(phi0 + s), cos(phi0 + s))``.
    """
    sn = math.sin(phi0 + s)
    cs = math.cos(phi0 + s)
    if s < sa:
        xb = x0 + v0 * s - 0.5 * gu * s * s
        vb = v0 - gu * s
        ab = -gu
    else:
        ts = s - sa
        xb = xa + va * ts - 0.5 * gd * ts * ts
        vb = va - gd * ts
        ab = -gd
    return xb - g * sn, vb - g * cs, ab + g * sn, sn, cs


@njit(cache=True)
def fly_sine(phi0, x0, v0, smax, g, gu, gd, al_u, al_d, htol, maxit, q0, q1, q2, q3, guess):
    """First contact after leaving ``(x0, v0)`` at ``phi0``: pure sine plate ``g sin(phi)``.

    Same contract as :func:`fly`: returns ``(s, landed, n_eval, p, p1, p2, p3)``, the
    contact is the first ``h <= htol`` with ``h' <= 0``, ``smax`` ends the search.  The
    certificates come from the curvature intervals (comment block above) instead of
    global derivative bounds.  ``al_u``, ``al_d``: :func:`sine_alpha` of ``(g, 1 + mu)`` and
    ``(g, 1 - mu)``; ``q0..q3``: the plate at ``phi0``; ``guess`` (rad, ``<= 0``: none): a
    predicted flight time (the previous flight's), used only to place trial points.

    A trial point ``x`` past the certified region is evaluated and then:
    ``h(x) <= 0`` with ``h(s) > 0`` on a convex or concave interval brackets exactly one
    crossing (the set ``h <= 0`` of a convex function is an interval; a concave
    function crosses downward once), solved by :func:`sine_bracket`; ``h(x) > 0`` clears
    ``[s, x]`` when ``h`` is concave there, or convex and still decreasing at ``x``.
    """
    if v0 > 0.0:
        sa = v0 / gu
        xa = x0 + 0.5 * v0 * sa
        va = 0.0
    else:
        sa = 0.0
        xa = x0
        va = v0
    split = gu != gd  # with friction the apex is a curvature edge (h'' jumps up by 2 mu)
    # the body passes below the plate's lowest point -g here: h <= 0 for certain
    s_floor = sa + (va + math.sqrt(va * va + 2.0 * gd * (xa + g))) / gd
    # the takeoff: rounding-sized h, h', h'' zeroed as in fly
    h = x0 - q0
    h1 = v0 - q1
    h2 = (-gu if v0 > 0.0 else -gd) - q2
    if abs(h) <= htol:
        h = 0.0
    if abs(h1) < 1e-12 * (1.0 + abs(v0)):
        h1 = 0.0
    if -1e-12 * (gu + g) < h2 < 0.0:
        h2 = 0.0
    sn = q0 / g if g > 0.0 else 0.0
    cs = q1 / g if g > 0.0 else 1.0
    if h <= htol and h1 <= 0.0 and (h1 < 0.0 or h < -htol or h2 < 0.0):
        return 0.0, True, 0, q0, q1, q2, q3  # lands at once (or a touch without separation)
    s = 0.0
    known = True  # h, h1, h2 are known at s (else only h(s) > 0 is)
    nev = 0
    for _ in range(maxit):
        up = s < sa
        convex, end = sine_region(phi0 + s, al_u if up else al_d)
        b = min(end - phi0, smax)
        if split and up and sa < b:
            b = sa
        if convex:
            if not known:  # (after the apex) the slope is needed
                h, h1, h2, sn, cs = sine_h(s, phi0, x0, v0, sa, xa, va, gu, gd, g)
                nev += 1
                known = True
                if h <= htol and h1 <= 0.0:
                    return sine_polish(s, h, h1, g, sn, cs, nev)
            tn = h / (-h1) if h1 < 0.0 else math.inf  # tangent (below h) reaches 0
            if s + tn >= b:
                # h' >= 0 (h increases) or the tangent stays positive: no contact before
                # b, and h(b) > 0 unless a root sits exactly on b
                if b >= smax:
                    return smax, False, nev, 0.0, 0.0, 0.0, 0.0
                s = b
                known = False
                continue
            if tn <= 1e-14 * (1.0 + s):
                return sine_polish(s, h, h1, g, sn, cs, nev)  # stalled on a tangency
            # trial point: the guess when it lies beyond the certified Newton point,
            # else the Halley point (longer than Newton's on a convex h)
            x = s + tn
            den = 1.0 - 0.5 * h * h2 / (h1 * h1)
            if s + tn < guess < b:
                x = guess
            elif den > 0.0:
                x = min(s + tn / den, b)
            hx, hx1, hx2, snx, csx = sine_h(x, phi0, x0, v0, sa, xa, va, gu, gd, g)
            nev += 1
            if hx <= 0.0:
                return sine_bracket(s, x, hx, hx1, hx2, snx, csx, phi0, x0, v0, sa, xa, va,
                                    gu, gd, g, nev)  # fmt: skip
            if hx1 < 0.0 or x == s + tn:
                # convex and decreasing up to x (or x the certified Newton point)
                s = x
                h, h1, h2, sn, cs = hx, hx1, hx2, snx, csx
                if h <= htol and h1 <= 0.0:
                    return sine_polish(s, h, h1, g, sn, cs, nev)
                continue
            # h(x) > 0 but h turned upward before x: only [s, s + tn) is certified
            s += tn
            h, h1, h2, sn, cs = sine_h(s, phi0, x0, v0, sa, xa, va, gu, gd, g)
            nev += 1
            if h <= htol and h1 <= 0.0:
                return sine_polish(s, h, h1, g, sn, cs, nev)
            continue
        # concave on [s, b] with h(s) > 0 (or = 0 with h' > 0)
        if known and h <= htol and h1 <= 0.0:
            return sine_polish(s, h, h1, g, sn, cs, nev)  # on the plate, not rising: contact
        x = min(b, s_floor)  # below the plate's lowest point at s_floor: h <= 0 there
        if known and h1 < 0.0:
            x = min(x, s + h / (-h1))  # the tangent (above h) reaches 0: h <= 0 there
        elif s < guess < x:
            x = guess
        elif known and h2 < 0.0:
            # rising: the root of the quadratic Taylor model (a guess, not a bound)
            x = min(x, s + (h1 + math.sqrt(h1 * h1 - 2.0 * h * h2)) / (-h2))
        hx, hx1, hx2, snx, csx = sine_h(x, phi0, x0, v0, sa, xa, va, gu, gd, g)
        nev += 1
        if hx > htol or (hx > 0.0 and hx1 > 0.0):
            # concave: h >= min(h(s), h(x)) > 0 on [s, x], no contact
            if x >= smax:
                return smax, False, nev, 0.0, 0.0, 0.0, 0.0
            s = x
            h, h1, h2, sn, cs = hx, hx1, hx2, snx, csx
            known = True
            continue
        if hx > 0.0:
            return sine_polish(x, hx, hx1, g, snx, csx, nev)  # within htol, descending
        return sine_bracket(s, x, hx, hx1, hx2, snx, csx, phi0, x0, v0, sa, xa, va, gu, gd,
                            g, nev)  # fmt: skip
    return s, True, maxit, g * sn, g * cs, -g * sn, -g * cs


@njit(cache=True)
def sine_polish(s, h, h1, g, sn, cs, nev):
    """Contact at ``s`` (``|h|`` at most ``htol`` or rounding): one Newton step onto the root.

    ``sn, cs``: sine and cosine of the phase at ``s``.  The plate state follows by Taylor
    (the step is below 1e-7, so dropped terms are below 1e-21).  Returns the tuple of
    :func:`fly_sine`.
    """
    p, p1, p2, p3 = g * sn, g * cs, -g * sn, -g * cs
    if h1 < 0.0 and h != 0.0:
        dt = h / (-h1)
        if abs(dt) < 1e-7:
            s += dt
            p += dt * (p1 + 0.5 * dt * p2)
            p1 += dt * (p2 + 0.5 * dt * p3)
            p2 += dt * p3
    return s, True, nev, p, p1, p2, p3


@njit(cache=True)
def sine_bracket(lo, x, h, h1, h2, sn, cs, phi0, x0, v0, sa, xa, va, gu, gd, g, nev):
    """The one crossing of ``h`` in ``(lo, x]`` given ``h(lo) > 0 >= h(x)`` (see fly_sine).

    Halley steps from the latest point, kept inside the bracket (Newton, then bisection
    as fallbacks); each evaluation narrows the bracket by the sign of ``h``, so the root
    cannot be lost.  A Halley or Newton step below 1e-6 rad leaves an error below
    rounding after the closing Newton step of :func:`sine_polish`.
    """
    hi = x
    for _ in range(200):
        if h == 0.0:
            break
        bis = False
        if h1 != 0.0:
            dn = -h / h1
            if abs(dn) <= 4e-16 * (1.0 + x):
                break  # on the root to rounding
            den = 1.0 - 0.5 * h * h2 / (h1 * h1)
            xn = x + (dn / den if den > 0.25 else dn)
            if not (lo < xn < hi):
                xn = x + dn
        else:
            xn = lo - 1.0
        if not (lo < xn < hi):
            xn = 0.5 * (lo + hi)
            bis = True
        if xn == x:
            break
        small = abs(xn - x) < 1e-6 * (1.0 + x)
        x = xn
        h, h1, h2, sn, cs = sine_h(x, phi0, x0, v0, sa, xa, va, gu, gd, g)
        nev += 1
        if h > 0.0:
            lo = x
        else:
            hi = x
        if (small and not bis) or hi - lo <= 4e-16 * (1.0 + hi):
            break
    return sine_polish(x, h, h1, g, sn, cs, nev)


@njit(cache=True)
def takeoff_ok(p1, p2, gu, gd):
    """Takeoff condition of a body riding the plate: plate accelerates down faster than gravity.

    Friction makes the threshold ``1 + mu`` while the plate (and body) moves up and
    ``1 - mu`` while it moves down.
    """
    if p1 > 0.0:
        return -p2 > gu
    return -p2 > gd


@njit(cache=True)
def takeoff_window(g, mu):
    """The takeoff set ``[lo, hi)`` within a cycle of a pure sine plate; ``lo = -1`` if empty.

    ``lo = arcsin((1+mu)/g)`` (or pi/2 when ``1 - mu < g <= 1 + mu``: the body leaves at
    the top as the plate turns down) and ``hi = pi - arcsin((1-mu)/g)``.
    """
    gd = 1.0 - mu
    gu = 1.0 + mu
    if g <= gd:
        return -1.0, -1.0
    # (the top is taken 2 ulp past pi/2 so that the plate velocity there is <= 0 in
    # floating point and the body leaves on its descending branch)
    lo = math.asin(gu / g) if g > gu else HALF_PI + 4.5e-16
    return lo, math.pi - math.asin(gd / g)


@njit(cache=True)
def ride_window(phi, phimax, lo, hi):
    """First phase ``>= phi`` inside the takeoff window ``[lo, hi)`` (mod 2 pi).

    Returns ``(phase, status)``: status 0 takeoff, 1 reached ``phimax``, 2 never (``lo < 0``).
    """
    if lo < 0.0:
        return phimax, 2
    n = math.floor(phi / TWO_PI)
    r = phi - n * TWO_PI
    if lo <= r < hi:
        cand = phi
    elif r < lo:
        cand = n * TWO_PI + lo
    else:
        cand = (n + 1.0) * TWO_PI + lo
    if cand >= phimax:
        return phimax, 1
    return cand, 0


@njit(cache=True)
def ride_general(
    phi, phimax, g, gu, gd, hk, ha, th, arm, ay, av, aref, lam, om, f2, m3, m4, maxit
):  # fmt: skip
    """First phase ``>= phi`` where the takeoff condition holds, any plate (certified stepping).

    ``q = -p'' - g_eff`` must become positive.  A move by ``t`` is certified when
    ``q_down = -p'' - (1 - mu)`` cannot reach 0 (second-derivative bound ``m4``), or when
    the plate keeps moving up (``p'`` bound ``m3``) while ``q_up`` cannot reach 0.
    Returns ``(phase, status)`` with status 0 takeoff, 1 reached ``phimax``, 2 gave up.
    """
    for _ in range(maxit):
        if phi >= phimax:
            return phimax, 1
        p, p1, p2, p3 = plate_eval(phi, g, hk, ha, th, arm, ay, av, aref, lam, om, f2)
        if takeoff_ok(p1, p2, gu, gd):
            return phi, 0
        qd = -p2 - gd
        qu = -p2 - gu
        t = 0.0
        if qd < 0.0:
            t = safe_step(-qd, p3, m4)
        if p1 > 0.0 and qu < 0.0:
            tb = min(safe_step(p1, p2, m3), safe_step(-qu, p3, m4))
            if tb > t:
                t = tb
        # a tangency of q with zero stalls the certified steps: creep past it
        phi += max(t, 1e-12 * (1.0 + abs(phi)))
    return phi, 2


@njit(cache=True)
def tv_sine(a, b, g):
    """Total variation of ``g sin`` over ``[a, b]``: the ride's path length."""
    n = math.ceil((a - HALF_PI) / math.pi)
    tp = HALF_PI + n * math.pi
    x = a
    tv = 0.0
    while tp < b:
        tv += abs(g * (math.sin(tp) - math.sin(x)))
        x = tp
        tp += math.pi
    return tv + abs(g * (math.sin(b) - math.sin(x)))


@njit(cache=True)
def tv_general(a, b, g, hk, ha, th, arm, ay, av, aref, lam, om, f2, m3, maxit):
    """Total variation of the plate position over ``[a, b]``, stepping between zeros of ``p'``.

    A zero of ``p'`` is approached by certified steps (``m3 >= sup|p'''|``) so that no
    turning point is skipped.
    """
    px = plate_eval(a, g, hk, ha, th, arm, ay, av, aref, lam, om, f2)[0]
    phi = a
    tv = 0.0
    for _ in range(maxit):
        p, p1, p2, p3 = plate_eval(phi, g, hk, ha, th, arm, ay, av, aref, lam, om, f2)
        sg = 1.0 if p1 >= 0.0 else -1.0
        t = safe_step(sg * p1, sg * p2, m3)
        t = max(t, 1e-12 * (1.0 + abs(phi)))
        if phi + t >= b:
            break
        phi += t
        p1n = plate_eval(phi, g, hk, ha, th, arm, ay, av, aref, lam, om, f2)[1]
        if p1n * sg <= 1e-13:  # reached a turning point
            pn = plate_eval(phi, g, hk, ha, th, arm, ay, av, aref, lam, om, f2)[0]
            tv += abs(pn - px)
            px = pn
    pb = plate_eval(b, g, hk, ha, th, arm, ay, av, aref, lam, om, f2)[0]
    return tv + abs(pb - px)


@njit(cache=True)
def ride_tv(a, b, g, hk, ha, th, arm, ay, av, aref, lam, om, f2, m3, maxit):
    """Path length of a body riding the plate from ``a`` to ``b``: the plate's total variation."""
    if b <= a:
        return 0.0
    if hk.shape[0] == 0 and not arm:
        return tv_sine(a, b, g)
    return tv_general(a, b, g, hk, ha, th, arm, ay, av, aref, lam, om, f2, m3, maxit)


@njit(cache=True)
def emit(out, row0, rows, max_rec, rec, n_skip):
    """Write ``rec`` as the next row unless it is a skipped transient; returns the new row count."""
    if rec[C_FLIGHT] >= n_skip and rows < max_rec:
        out[:, row0 + rows] = rec
        return rows + 1
    return rows


@njit(cache=True)
def trajectory(
    par, hk, ha, hpsi, g_true, g_stated, step_end, init_ride, phi_init, x_init, v_init,
    n_skip, max_rec, settle, start_id, out, row0,
):  # fmt: skip
    """Run one trajectory through a schedule of Gamma steps; write flight rows into ``out``.

    ``g_true``/``g_stated``: Gamma per step, shape ``(n_steps,)`` (true drives the plate,
    stated is recorded); ``step_end[i]``: the drive cycle (since the start) at which
    step ``i`` ends.  Starts riding the plate at ``phi_init`` (``init_ride``) or flying
    from ``(x_init, v_init)`` at ``phi_init``.  Flights with index ``< n_skip`` are not
    written; at most ``max_rec`` rows go to ``out[:, row0:row0 + max_rec]``.  Returns
    ``(rows_written, status)``.

    A flight row is complete at the next takeoff: its energy terms include its landing
    impact (or the whole summed chatter tail) and the ride that follows.  A change of
    Gamma takes effect at the step's first phase (a multiple of 2 pi, where the
    fundamental's position is continuous) whatever the body is doing.
    """
    mu = par[P_MU]
    e = par[P_E]
    r = par[P_R]
    f = par[P_F]
    lam = par[P_Z] * f
    f2 = f * f
    om = f2 - lam * lam
    eps_t = par[P_EPS]
    htol = par[P_HTOL]
    cap = int(par[P_CAP])
    ride_max = par[P_RIDE]
    gu = 1.0 + mu
    gd = 1.0 - mu
    use_arm = r > 0.0
    nh = hk.shape[0]
    a0 = 0.0
    a2 = 0.0
    a3 = 0.0
    a4 = 0.0
    for j in range(nh):
        aj = abs(ha[j])
        a0 += aj
        a2 += aj * hk[j] ** 2
        a3 += aj * hk[j] ** 3
        a4 += aj * hk[j] ** 4
    th = hpsi.copy()
    nsteps = g_true.shape[0]
    maxit = 200000

    fast = par[P_FAST] > 0.0 and nh == 0 and not use_arm  # pure sine plate: fly_sine
    g_al = -1.0  # Gamma of the cached curvature edges (fly_sine)
    al_u = -1.0
    al_d = -1.0
    g_win = -1.0  # Gamma of the cached takeoff window (pure sine plate)
    lo_win = -1.0
    hi_win = -1.0
    sn_win = 0.0  # sin and cos of lo_win
    cs_win = 1.0
    k = 0  # current step
    g = g_true[0]
    ncyc = 0  # whole drive cycles removed from the phase frame
    ay = 0.0  # armature deflection and velocity at phase aref
    av = 0.0
    aref = 0.0
    arm = False  # armature excited yet?

    rows = 0
    n_fl = 0  # flights started
    pend = False  # rec holds a landed flight whose ride is still running
    rec = np.zeros(NCOL)
    cur = np.zeros(NCOL)

    phi = phi_init
    riding = init_ride
    x0 = x_init
    v0 = v_init
    ride_search = phi  # where the takeoff search starts (after a summed chatter tail)
    chatter = False
    qa_ok = False  # plate state at the ride's start known (from the impact)?
    tq_ok = False  # plate state at the takeoff known (tq0..tq3)?
    tq0 = 0.0
    tq1 = 0.0
    tq2 = 0.0
    tq3 = 0.0
    qa0 = 0.0
    qa1 = 0.0
    qa2 = 0.0
    qa3 = 0.0
    n_imp = 0  # flights in the current chatter sequence
    t_prev = 0.0  # the previous flight's duration

    while True:
        if riding:
            # ---- ride with the plate until the takeoff condition holds ----
            # energy: riding, the normal force does work [chi_p'^2/2 + chi_p] + mu TV(chi_p)
            # and friction takes mu TV(chi_p); (qa0, qa1) is the plate state at phi_e
            phi_e = phi
            if not qa_ok:
                qa0, qa1, _, _ = plate_eval(phi_e, g, hk, ha, th, arm, ay, av, aref, lam, om, f2)
            found = False
            stuck = False
            while True:
                bound = TWO_PI * (step_end[k] - ncyc)
                lim = min(bound, ride_search + ride_max)
                if arm:
                    b0, b2, b3, b4 = arm_bounds(ay, av, f, lam)
                else:
                    b0, b2, b3, b4 = 0.0, 0.0, 0.0, 0.0
                m3 = g * (1.0 + a3) + b3
                m4 = g * (1.0 + a4) + b4
                if nh == 0 and not arm:
                    if g != g_win:  # the window depends on Gamma only: computed once per step
                        lo_win, hi_win = takeoff_window(g, mu)
                        sn_win = math.sin(lo_win)
                        cs_win = math.cos(lo_win)
                        g_win = g
                    pt, st = ride_window(ride_search, lim, lo_win, hi_win)
                elif g * (1.0 + a2) + b2 <= gd:
                    pt, st = lim, 2  # the plate can never out-accelerate gravity
                else:
                    pt, st = ride_general(
                        ride_search, lim, g, gu, gd, hk, ha, th, arm, ay, av, aref,
                        lam, om, f2, m3, m4, maxit,
                    )  # fmt: skip
                if st != 0 and pt < bound and k < nsteps - 1:
                    pt = bound  # no takeoff at this Gamma: the body rides on to the next step
                if fast and st == 0 and qa_ok and pt == phi_e:
                    # takes off where it landed: the plate state is the contact's
                    pb0, pb1, pb2, pb3 = qa0, qa1, qa2, qa3
                elif fast and st == 0 and pt != ride_search:
                    # a window start lo + 2 pi n: the plate there in closed form
                    pb0, pb1, pb2, pb3 = g * sn_win, g * cs_win, -g * sn_win, -g * cs_win
                else:
                    pb0, pb1, pb2, pb3 = plate_eval(
                        pt, g, hk, ha, th, arm, ay, av, aref, lam, om, f2
                    )  # fmt: skip
                if pend:
                    fr_ = 0.0
                    if mu > 0.0:
                        fr_ = mu * ride_tv(
                            phi_e, pt, g, hk, ha, th, arm, ay, av, aref, lam, om, f2, m3, maxit
                        )
                    rec[C_EPLATE] += 0.5 * (pb1 * pb1 - qa1 * qa1) + (pb0 - qa0) + fr_
                    rec[C_EFRIC] += fr_
                phi_e = pt
                qa0 = pb0
                qa1 = pb1
                if st == 0:
                    phi = pt
                    found = True
                    tq0, tq1, tq2, tq3 = pb0, pb1, pb2, pb3  # plate at the takeoff
                    tq_ok = True
                    break
                if k == nsteps - 1:
                    stuck = pt < bound
                    break  # stuck for good, or the protocol ends during the ride
                # step boundary: the plate switches amplitude under the riding body
                k += 1
                g = g_true[k]
                pb0, pb1, _, _ = plate_eval(bound, g, hk, ha, th, arm, ay, av, aref, lam, om, f2)
                if pend:  # the plate's jump in velocity (and position) is work on the body
                    rec[C_EPLATE] += 0.5 * (pb1 * pb1 - qa1 * qa1) + (pb0 - qa0)
                qa0 = pb0
                qa1 = pb1
                phi_e = bound
                ride_search = bound
            if not found:
                if pend and stuck:
                    # the last flight's ride never ends: energy counted to the give-up point
                    rows = emit(out, row0, rows, max_rec, rec, n_skip)
                return rows, ST_STUCK if stuck else ST_END
            x0 = qa0
            v0 = qa1
            chatter = False
            riding = False

        # ---- flight ----
        # move the frame so that 0 <= phi < 2 pi (harmonic offsets and armature follow)
        if phi >= TWO_PI or phi < 0.0:
            nn = math.floor(phi / TWO_PI)
            phi -= nn * TWO_PI
            ncyc += int(nn)
            for j in range(nh):
                kn = hk[j] * nn
                th[j] = (th[j] + TWO_PI * (kn - math.floor(kn))) % TWO_PI
            aref -= nn * TWO_PI
        for c in range(NCOL):
            cur[c] = 0.0
        cur[C_GAMMA] = g_stated[k]
        cur[C_PHI0] = phi
        cur[C_START] = start_id
        cur[C_STEP] = k
        cur[C_TTO] = TWO_PI * ncyc + phi
        step_start = step_end[k - 1] if k > 0 else 0
        cur[C_SETTLED] = 1.0 if cur[C_TTO] >= TWO_PI * (step_start + settle) - 1e-9 else 0.0
        cur[C_X0] = x0
        cur[C_V0] = v0
        cur[C_FLIGHT] = n_fl

        if arm:
            b0, b2, b3, b4 = arm_bounds(ay, av, f, lam)
        else:
            b0, b2, b3, b4 = 0.0, 0.0, 0.0, 0.0
        phis = phi  # segment start (a flight may cross step boundaries)
        k_to = k
        total = 0.0
        ended = False
        nit_tot = 0
        s = 0.0
        while True:
            m2 = gu + g * (1.0 + a2) + b2
            m3 = g * (1.0 + a3) + b3
            m4 = g * (1.0 + a4) + b4
            pmax = g * (1.0 + a0) + b0
            bound = TWO_PI * (step_end[k] - ncyc)
            if not tq_ok:
                tq0, tq1, tq2, tq3 = plate_eval(phis, g, hk, ha, th, arm, ay, av, aref, lam, om, f2)
            if fast:
                if g != g_al:  # curvature edges depend on Gamma only: once per step
                    al_u = sine_alpha(g, gu)
                    al_d = sine_alpha(g, gd)
                    g_al = g
                s, landed, nit, p, p1, p2, p3 = fly_sine(
                    phis, x0, v0, bound - phis, g, gu, gd, al_u, al_d, htol, maxit,
                    tq0, tq1, tq2, tq3, t_prev,
                )  # fmt: skip
            else:
                s, landed, nit, p, p1, p2, p3 = fly(
                    phis, x0, v0, bound - phis, g, gu, gd, hk, ha, th, arm, ay, av, aref,
                    lam, om, f2, m2, m3, m4, pmax, htol, maxit, tq0, tq1, tq2, tq3,
                )  # fmt: skip
            tq_ok = False
            nit_tot += nit
            cur[C_EFRIC] += mu * path_length(s, x0, v0, gu, gd)
            total += s
            if landed:
                break
            # step boundary in flight: the body flies on, the plate switches amplitude
            xb, vb, _ = body_eval(s, x0, v0, gu, gd)
            if k == nsteps - 1:
                ended = True
                break
            k += 1
            g = g_true[k]
            x0 = xb
            v0 = vb
            phis = bound
        if ended:
            if pend:  # its ride ended with this takeoff: complete
                rows = emit(out, row0, rows, max_rec, rec, n_skip)
            return rows, ST_END
        if total == 0.0 and k == k_to:
            # no real flight (a touch of the takeoff line without crossing it): ride on
            riding = True
            qa_ok = False
            ride_search = phi + 1e-9
            continue
        if pend:
            rows = emit(out, row0, rows, max_rec, rec, n_skip)
            pend = False
            if rows >= max_rec:
                return rows, ST_FULL
        n_fl += 1
        phil = phis + s
        cur[C_T] = total
        cur[C_PHIL] = phil % TWO_PI
        # chatter: a rebound from the sticking region shorter than the flight before it,
        # i.e. part of a decaying sequence of impacts heading for sticking
        if chatter and total < t_prev:
            cur[C_CHAT] = 1.0
            n_imp += 1
        else:
            n_imp = 0
        t_prev = total
        cur[C_NSTEPS] = nit_tot

        # ---- impact ---- (p, p1, p2: the plate at the contact, from fly)
        xb, vb, _ = body_eval(s, x0, v0, gu, gd)
        u = min(vb - p1, 0.0)
        cur[C_VIMP] = u
        stick_here = not takeoff_ok(p1, p2, gu, gd)
        # does the chatter end here?  Predict the next micro-flight with the plate's
        # acceleration frozen: the body rises with relative deceleration c1, falls with c2.
        w = -e * u
        tau = 0.0
        eff_e = e
        if w > 0.0:
            c1 = (gu if p1 + w > 0.0 else gd) + p2
            c2 = (gu if p1 > 0.0 else gd) + p2
            if c1 > 0.0 and c2 > 0.0:
                tm = w / c1 + w / math.sqrt(c1 * c2)
                rho = e * math.sqrt(c2 / c1)
                if (tm < eps_t or n_imp >= cap) and rho < 1.0:
                    eff_e = 0.0
                    tau = tm / (1.0 - rho)  # the summed geometric tail of micro-flights
                    cur[C_TAIL] = tau
        jmp = (1.0 + eff_e) * (-u) / (1.0 + r)  # body velocity change (two-body impact)
        cur[C_EIMP] = (1.0 - eff_e * eff_e) * u * u / (2.0 * (1.0 + r))
        cur[C_EPLATE] += jmp * p1 - r * jmp * jmp / 2.0
        if use_arm:
            # re-reference the armature at the impact; it recoils by -r * jmp
            if arm:
                yy, yv, _, _ = arm_eval(phil - aref, ay, av, lam, om, f2)
            else:
                yy = 0.0
                yv = 0.0
            ay = yy
            av = yv - r * jmp
            aref = phil
            arm = True
        phi = phil
        if eff_e > 0.0 and w > 0.0:
            # rebound: this row is complete, the next flight starts at once
            x0 = p
            v0 = vb + jmp
            chatter = stick_here
            if not use_arm:  # the plate at the next takeoff is the plate at this contact
                tq0, tq1, tq2, tq3 = p, p1, p2, p3
                tq_ok = True
            rows = emit(out, row0, rows, max_rec, cur, n_skip)
            if rows >= max_rec:
                return rows, ST_FULL
            continue
        # inelastic (or the chatter tail summed): the body rides from here
        qa_ok = not use_arm  # the armature's recoil changed the plate's velocity
        qa0 = p
        qa1 = p1
        qa2 = p2
        qa3 = p3
        rec[:] = cur
        pend = True
        riding = True
        ride_search = phil + tau


@njit(cache=True, parallel=True)
def run_many(
    par, hk, ha, hpsi, g_true, g_stated, step_end, init_ride, phi_init, x_init, v_init,
    n_skip, max_rec, settle, start_id, out,
):  # fmt: skip
    """Independent trajectories in parallel: row ``i`` of ``g_true`` etc. is trajectory ``i``.

    ``g_true``, ``g_stated``: ``(n_traj, n_steps)``; ``step_end``: ``(n_steps,)``;
    ``phi_init``, ``x_init``, ``v_init``, ``start_id``: ``(n_traj,)``;
    ``out``: ``(NCOL, n_traj * max_rec)`` (one contiguous row per column).
    Returns ``(rows, status)``, arrays of shape ``(n_traj,)``.
    """
    n = g_true.shape[0]
    rows = np.zeros(n, dtype=np.int64)
    status = np.zeros(n, dtype=np.int64)
    for i in prange(n):
        rw, st = trajectory(
            par, hk, ha, hpsi, g_true[i], g_stated[i], step_end, init_ride, phi_init[i],
            x_init[i], v_init[i], n_skip, max_rec, settle, start_id[i], out, i * max_rec,
        )  # fmt: skip
        rows[i] = rw
        status[i] = st
    return rows, status
