"""numba kernels of the event-driven impact map (nondimensional units, see docs/physics.md).

Small compiled functions only; :mod:`bouncelab.physics.simulate` arranges them and
builds DataFrames.  Units: phase ``phi`` (rad), heights in ``g / omega^2``,
velocities in ``g / omega``, energies per unit body mass in ``(g / omega)^2``.

Model parameters travel in one float64 vector ``par`` (indices ``P_*``) plus three
arrays for the harmonics (``hk``, ``ha``, ``hpsi``, shape ``(n_harmonics,)``).  Output
rows are written into a float64 matrix ``out[column, row]`` with the column indices
``C_*``.

Every kernel is compiled with ``cache=True`` and ``error_model="numpy"``: a division by
zero would give inf or nan instead of raising (none occurs for valid parameters), which
spares every division in the inner loops its zero test and branch. The small helpers
(``@inlined``: the plate's and the body's evaluations, the walks' steps and bounds) are
also inlined into their callers by numba itself: a non-sine plate is evaluated 5-7 times
a ride and 3-4 times a landing, and inlined, an armature or harmonic simulation takes
12-18 % less time than with those evaluations as calls. The numbers are the same to the
last bit (no floating-point operation changes); the price is a longer first compile,
42 s instead of 29 s, once per install (docs/diagnosis-log.md, session 55).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

TWO_PI = 2.0 * math.pi
HALF_PI = 0.5 * math.pi

#: The decorator of the small helpers: a kernel inlined at numba's level into its callers.
inlined = njit(cache=True, error_model="numpy", inline="always")

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
P_LOAD = 11  # ride_load: share of a riding body's contact force that loads the armature
P_ENERGY = 12  # 1.0: the energy columns complete; 0.0: friction's ride term skipped (fits)
P_ALLCOLS = 13  # 1.0: every output column written; 0.0: only FIT_COLUMNS (fits)
P_STICK = 14  # sticking speed (g / omega): a rebound slower than this sticks (0: none)
NPAR = 15

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
C_SETTLED = 12  # 1.0 unless the takeoff is within settle cycles of its step start or
#   the change of Gamma itself ends the flight (CAUGHT)
C_X0 = 13  # body height at takeoff
C_V0 = 14  # body velocity at takeoff (lab frame)
C_FLIGHT = 15  # flight index in the trajectory (skipped transients included)
C_NSTEPS = 16  # plate evaluations spent on this flight's landing search (diagnostic)
C_TAIL = 17  # duration (rad) of the summed chatter tail after this flight's landing, else 0
NCOL = 18

#: The columns a fit reads (:func:`protocol_rows`). Why a fit's kernel writes only these:
#: each column is its own row of ``out``, megabytes from the next, so every flight's 18
#: stores touched 18 pages; 5 take 7-10 % off one friction + restitution + harmonic
#: evaluation (session 35; within the noise of whole diagnoses).
FIT_COLUMNS = (C_T, C_TTO, C_START, C_STEP, C_SETTLED)

#: rad: a flight that lands within this of a change of Gamma it flew across was caught by
#: the change itself (the plate's velocity jumps there): not settled (:func:`trajectory`).
#: Such a landing is at the change to rounding (1e-9 rad measured); a real one that close
#: would need a flight aimed at that instant to 1e-6 rad (50 ns at 20 Hz).
CAUGHT = 1e-6

HIST = 4  # recent flights remembered for the guess of the next flight's duration

# trajectory status codes
ST_DONE = 0  # recorded what was asked
ST_STUCK = 1  # the body can no longer take off (e.g. Gamma <= 1 for ideal)
ST_END = 2  # the protocol's last step ended
ST_FULL = 3  # the output buffer is full before the protocol ended


@inlined
def mod_two_pi(x):
    """``x mod 2 pi`` for ``x >= 0``, equal to ``x % TWO_PI`` (an exact fmod) bit for bit.

    Cheaper than the library ``fmod`` for the usual few cycles: ``TWO_PI`` has 50
    significant bits, so ``n * TWO_PI`` is exact for ``n <= 7`` and so is the difference
    (the exact remainder is representable).  A quotient that rounded up to ``n`` gives a
    tiny negative remainder, corrected by adding ``TWO_PI`` back (exact as well).
    """
    n = np.floor(x / TWO_PI)
    if n > 7.0:
        return x % TWO_PI  # (Python semantics: fmod for x >= 0)
    r = x - n * TWO_PI
    if r < 0.0:
        r += TWO_PI
    return r


@inlined
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


@inlined
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


@inlined
def armature_kick(p, p1, p2, p3, dv, lam, f2):
    """Plate state just after the armature's velocity jumps by ``dv`` (an impact's recoil).

    The deflection is continuous; ``y'' = -2 lam y' - f2 y`` and its derivative carry
    the jump to the second and third derivatives.
    """
    return p, p1 + dv, p2 - 2.0 * lam * dv, p3 + (4.0 * lam * lam - f2) * dv


@inlined
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


@inlined
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


@njit(cache=True, error_model="numpy")
def ride_coefficients(hk, f2, lam, load):
    """Forced response of the armature to a riding body, per plate component.

    While the body rides, the contact force ``n = chi_p'' + 1 + mu sigma`` (weight,
    inertia, friction on the guide; ``sigma`` the sign of the plate velocity) loads the
    armature: ``(1 + L) y'' + 2 lam y' + f2 y = -L (c'' + 1 + mu sigma)`` with
    ``L = load * mass_ratio`` and ``c`` the commanded plate.  For a component
    ``a sin(k phi + th)`` of ``c / g`` the particular solution is
    ``g a (P sin(k phi + th) + Q cos(k phi + th))`` with ``M = f2 - (1 + L) k^2``,
    ``D = M^2 + (2 lam k)^2``, ``P = L k^2 M / D``, ``Q = -2 lam k^3 L / D``.

    Returns ``rp``, shape ``(2 (n_harmonics + 1) + 1,)``: ``P, Q`` of the fundamental,
    then of each harmonic, and a last slot for the constant part (set per ride segment
    by :func:`ride_constant`).
    """
    nh = hk.shape[0]
    rp = np.zeros(2 * (nh + 1) + 1)
    for j in range(nh + 1):
        k = 1.0 if j == 0 else hk[j - 1]
        m = f2 - (1.0 + load) * k * k
        c = 2.0 * lam * k
        d = m * m + c * c
        rp[2 * j] = load * k * k * m / d
        rp[2 * j + 1] = -load * k * k * c / d
    return rp


@njit(cache=True, error_model="numpy")
def ride_bounds(ha, hk, rp):
    """``sum_j |a_j| k_j^n |P_j + i Q_j|`` for ``n = 2, 3, 4``: bounds (over g) of the
    forced response's derivatives."""
    r = math.hypot(rp[0], rp[1])
    b2 = r
    b3 = r
    b4 = r
    for j in range(hk.shape[0]):
        r = abs(ha[j]) * math.hypot(rp[2 * j + 2], rp[2 * j + 3])
        b2 += r * hk[j] ** 2
        b3 += r * hk[j] ** 3
        b4 += r * hk[j] ** 4
    return b2, b3, b4


@inlined
def ride_particular(phi, g, hk, ha, th, rp):
    """The armature's forced response to a riding body and its first three derivatives.

    ``rp`` from :func:`ride_coefficients`, its last slot the constant (static) part.
    """
    sn = math.sin(phi)
    cs = math.cos(phi)
    u = rp[0] * sn + rp[1] * cs
    w = rp[0] * cs - rp[1] * sn
    p = u
    p1 = w
    p2 = -u
    p3 = -w
    for j in range(hk.shape[0]):
        k = hk[j]
        arg = k * phi + th[j]
        sj = math.sin(arg)
        cj = math.cos(arg)
        u = ha[j] * (rp[2 * j + 2] * sj + rp[2 * j + 3] * cj)
        w = ha[j] * (rp[2 * j + 2] * cj - rp[2 * j + 3] * sj)
        p += u
        p1 += k * w
        p2 -= k * k * u
        p3 -= k * k * k * w
    return g * p + rp[rp.shape[0] - 1], g * p1, g * p2, g * p3


@inlined
def plate_eval_ride(phi, g, hk, ha, th, arm, ay, av, aref, lam, om, f2, rp):
    """:func:`plate_eval`, plus the forced response to a riding body when ``rp`` is not
    empty (then ``ay, av, aref, lam, om, f2`` describe the free part of the loaded
    armature)."""
    p, p1, p2, p3 = plate_eval(phi, g, hk, ha, th, arm, ay, av, aref, lam, om, f2)
    if rp.shape[0] > 0:
        y, y1, y2, y3 = ride_particular(phi, g, hk, ha, th, rp)
        p += y
        p1 += y1
        p2 += y2
        p3 += y3
    return p, p1, p2, p3


@inlined
def plate_direction(p1, p2):
    """Sign of the plate velocity, or of its acceleration where the velocity is zero."""
    if abs(p1) > 1e-13:
        return 1.0 if p1 > 0.0 else -1.0
    return 1.0 if p2 >= 0.0 else -1.0


@inlined
def ride_armature(phi, g, hk, ha, th, ay, av, aref, lam, om, f2, rp):
    """Deflection and velocity of the loaded armature: free part plus forced part."""
    y, y1, _, _ = arm_eval(phi - aref, ay, av, lam, om, f2)
    yp, yp1, _, _ = ride_particular(phi, g, hk, ha, th, rp)
    return y + yp, y1 + yp1


@inlined
def ride_rebase(phi, y, y1, g, hk, ha, th, rp, load, f2, mu, sigma):
    """Free part ``(ay, av)`` at ``phi`` of a loaded armature at deflection ``y``, velocity
    ``y1``, for plate direction ``sigma`` (sets ``rp``'s constant, :func:`ride_constant`)."""
    ride_constant(rp, load, f2, mu, sigma)
    yp, yp1, _, _ = ride_particular(phi, g, hk, ha, th, rp)
    return y - yp, y1 - yp1


@inlined
def ride_constant(rp, load, f2, mu, sigma):
    """Set the static part of the forced response: ``-L (1 + mu sigma) / f2``."""
    rp[rp.shape[0] - 1] = -load * (1.0 + mu * sigma) / f2


@inlined
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


@inlined
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


@inlined
def body_apex(x0, v0, gu):
    """Phase since takeoff, height and velocity of the body's apex ``(sa, xa, va)``.

    A body leaving downward (``v0 <= 0``) has its "apex" at the takeoff: ``(0, x0, v0)``.
    """
    if v0 > 0.0:
        sa = v0 / gu
        return sa, x0 + 0.5 * v0 * sa, 0.0
    return 0.0, x0, v0


@inlined
def body_at(s, x0, v0, sa, xa, va, gu, gd):
    """Body height, velocity and acceleration ``s`` after takeoff, given its apex.

    ``sa``, ``xa``, ``va``: time, height and velocity at the apex (for ``v0 <= 0``: 0,
    ``x0``, ``v0``); effective gravity ``gu`` before it, ``gd`` after it (friction).
    """
    if s < sa:
        return x0 + v0 * s - 0.5 * gu * s * s, v0 - gu * s, -gu
    ts = s - sa
    return xa + va * ts - 0.5 * gd * ts * ts, va - gd * ts, -gd


@inlined
def taylor_step(h, h1, h2, h3, m2, m3, m4):
    """Certified step of the landing walk from a point with ``h >= 0`` (bounds 1-3 of fly).

    ``h, h1, h2, h3``: the relative height and its first three derivatives (phase units);
    ``m2 >= sup(-h'')``, ``m3 >= sup|h'''|``, ``m4 >= sup|h''''|``.  Returns the largest
    ``t`` for which one of the lower bounds of :func:`fly` is positive on ``(0, t)``.
    """
    t = safe_step(h, h1, m2)
    if h1 >= 0.0 and h2 >= 0.0 and h1 < 1e-2:
        # near a takeoff with small relative velocity the quadratic bound stalls; the
        # cubic bound holds while any one non-negative Taylor term beats m3 t^3/6
        t3 = 3.0 * h2 / m3
        if h1 > 0.0:
            t3 = max(t3, math.sqrt(6.0 * h1 / m3))
        if h > 0.0:
            t3 = max(t3, (6.0 * h / m3) ** (1.0 / 3.0))
        if t3 > t:
            t = t3
        if h3 > 0.0:
            t4 = max(4.0 * h3 / m4, math.sqrt(12.0 * h2 / m4))
            if h1 > 0.0:
                t4 = max(t4, (24.0 * h1 / m4) ** (1.0 / 3.0))
            if h > 0.0:
                t4 = max(t4, math.sqrt(math.sqrt(24.0 * h / m4)))
            if t4 > t:
                t = t4
    return t


@inlined
def trial_bounds(hx, hx1, m2):
    """Where the backward bound from a trial point ``x`` certifies ``h > 0`` (bound 5 of fly).

    ``h(x - d) >= hx - hx1 d - m2 d^2 / 2 > 0`` for ``lo < d < hi``.  Returns
    ``(hi, lo)``; ``hi <= 0`` when the bound certifies nothing (``h`` rising into or below
    the plate at ``x``, or too deep below it).  ``lo < 0`` when ``hx > 0``.
    """
    b = -hx1
    disc = b * b + 2.0 * m2 * hx
    if disc <= 0.0 or (hx <= 0.0 and b <= 0.0):
        return -1.0, 0.0
    sq = math.sqrt(disc)
    if b >= 0.0:
        return (b + sq) / m2, -2.0 * hx / (b + sq)
    return 2.0 * hx / (sq - b), (b - sq) / m2


@inlined
def next_trial(s, h, h1, h2, reach, guess, pending, ct, m2):
    """Where :func:`fly` places its next trial point (phase offset; -1: none).

    At the takeoff the guess, if beyond the walk's reach; later, while descending, the
    root of the quadratic Taylor model at ``s`` (``h, h1, h2``: relative height and
    derivatives there), but only where bound 5 is expected to hold at once with the
    slope the model predicts there (near a tangency it would not, and the walk is
    cheaper), and before a pending trial point's certified region (from ``ct`` on).
    """
    if s == 0.0 and guess > reach:
        return guess
    if h1 >= 0.0:
        return -1.0
    disc = h1 * h1 - 2.0 * h * h2
    d = 2.0 * h / (math.sqrt(disc) - h1) if disc > 0.0 else h / (-h1)
    slope = h1 + h2 * d  # h' expected at the trial point
    if reach < s + d < reach - 2.0 * slope / m2 and (not pending or s + d < ct):
        return s + d
    return -1.0


@njit(cache=True, error_model="numpy")
def fly(
    phi0, x0, v0, smax, g, gu, gd, hk, ha, th, arm, ay, av, aref, lam, om, f2,
    m2, m3, m4, pmax, htol, maxit, q0, q1, q2, q3, guess,
):  # fmt: skip
    """First contact after leaving ``(x0, v0)`` at phase ``phi0``.

    ``q0..q3``: the plate's position and first three derivatives at ``phi0`` (known to
    the caller from the takeoff); ``guess`` (rad, ``<= 0``: none): a predicted flight
    time (:func:`predict_flight`), used only to place a trial point.  Returns
    ``(s, landed, n_eval, p, p1, p2, p3)``: the flight time, whether it landed (False:
    reached ``smax``), the plate evaluations, and the plate position and derivatives at
    the contact (zeros when not landed).

    ``h(s) = x_body(s) - chi_p(phi0 + s)`` is the relative height.  No-skip argument:
    the walk keeps a certified reach ``R`` (``h > 0`` on ``[0, R)``); every extension is
    proven by a lower bound of ``h``:

    1. ``h + h' t - m2 t^2/2`` with ``m2 >= sup(-h'')`` (gravity + plate acceleration bound);
    2. ``h + h' t + h'' t^2/2 - m3 t^3/6`` and 3. the quartic analogue with
       ``m3 >= sup|p'''|``, ``m4 >= sup|p''''|``, used when the lower derivatives are >= 0
       (a takeoff on or near the takeoff line, where ``h`` grows like ``s^3``); the only
       jump of ``h''`` is upward (at the apex friction flips sign), so these Taylor bounds
       stay valid;
    4. ``x_body > pmax >= max chi_p``: the body's height is a concave curve, so once the
       reach is inside the span where it is above the plate's range, the whole span is
       clear;
    5. backward from a trial point ``x`` (the guess, or the predicted root of the
       quadratic Taylor model while descending): ``h(x - d) >= h(x) - h'(x) d - m2 d^2/2``
       is positive for ``lo < d < hi`` (:func:`trial_bounds`).  Once ``R >= x - hi``,
       ``h > 0`` on ``[0, x - max(lo, 0))``: with ``h(x) > htol`` the walk moves to ``x``;
       otherwise the first contact lies in ``[x - lo, x]``, where ``h`` is strictly
       decreasing (``lo <= |h'(x)|/m2``, so ``h' <= h'(x) + m2 d < 0`` there), and
       Newton steps from ``x`` kept inside that bracket find it.

    The first ``s`` where ``h <= htol`` while ``h' <= 0`` is the contact (a graze counts
    when it comes within ``htol``).  Once ``h <= 1e-6`` with ``h' < -0.1`` at a walk point
    (a clearly transversal approach) Newton steps finish: each overshoots the certified
    step by at most ``m2 h^2 / (2 |h'|^3) < 1e-9 m2``, far too short for a contact to hide
    in (its depth would be below ``m2 * 1e-18``).  If the flight reaches ``smax`` (a
    protocol step boundary) it stops there.
    """
    # the body's apex, once (friction: two parabolas joined there)
    sa, xa, va = body_apex(x0, v0, gu)
    # the time the body comes down through pmax (if it rises above it at all)
    s_desc = -1.0
    if xa > pmax:
        s_desc = sa + (va + math.sqrt(va * va + 2.0 * gd * (xa - pmax))) / gd
    s = 0.0
    p, p1, p2, p3 = q0, q1, q2, q3
    nev = 0
    # the pending trial point: phase offset xt (< 0: none), h and h' there, the plate
    # there, and where its backward bound starts (ct) and ends (the bracket's low end)
    xt = -1.0
    ht = 0.0
    ht1 = 0.0
    ct = 0.0
    dlo = 0.0
    pt0 = 0.0
    pt1 = 0.0
    pt2 = 0.0
    pt3 = 0.0
    fresh = True  # p..p3 hold the plate at s
    for _ in range(maxit):
        if not fresh:
            p, p1, p2, p3 = plate_eval(phi0 + s, g, hk, ha, th, arm, ay, av, aref, lam, om, f2)
            nev += 1
        fresh = False
        xb, vb, ab = body_at(s, x0, v0, sa, xa, va, gu, gd)
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
            return fly_newton(s, h, h1, p, p1, p2, p3, -math.inf, math.inf, 4, phi0, x0, v0,
                              sa, xa, va, g, gu, gd, hk, ha, th, arm, ay, av, aref, lam, om,
                              f2, htol, nev)  # fmt: skip
        # contact: within htol of the plate and not moving away from it (a body just
        # above the plate but rising, e.g. after a tiny rebound, is still in flight)
        if h <= htol and h1 <= 0.0 and (s > 0.0 or h1 < 0.0 or h < -htol):
            return contact_polish(s, h, h1, p, p1, p2, p3, nev)
        t = taylor_step(max(h, 0.0), h1, h2, -p3, m2, m3, m4)
        if s_desc - s > t and (xb > pmax or body_at(s + t, x0, v0, sa, xa, va, gu, gd)[0] > pmax):
            t = s_desc - s  # above the plate's whole range until then (bound 4)
        if t <= 1e-14 * (1.0 + s):
            return s, True, nev, p, p1, p2, p3  # stalled on a tangency: contact within rounding
        reach = s + t
        # a trial point where the landing is expected (bound 5)
        x = next_trial(s, h, h1, h2, reach, guess, xt >= 0.0, ct, m2)
        if 0.0 < x < smax:
            qx0, qx1, qx2, qx3 = plate_eval(phi0 + x, g, hk, ha, th, arm, ay, av, aref, lam, om, f2)
            nev += 1
            bx, bx1, _ = body_at(x, x0, v0, sa, xa, va, gu, gd)
            hi, lo = trial_bounds(bx - qx0, bx1 - qx1, m2)
            if hi > 0.0:
                xt = x
                ht = bx - qx0
                ht1 = bx1 - qx1
                ct = x - hi
                dlo = x - max(lo, 0.0)
                pt0, pt1, pt2, pt3 = qx0, qx1, qx2, qx3
        if xt >= 0.0 and reach >= ct:
            # the walk has met the trial point's certified neighbourhood
            if ht > htol or (ht > 0.0 and ht1 > 0.0):
                # clear up to the trial point (just above the plate but rising there is
                # no contact): the walk goes on from it
                s = xt
                p, p1, p2, p3 = pt0, pt1, pt2, pt3
                fresh = True
                xt = -1.0
                continue
            if ht > 0.0:
                return contact_polish(xt, ht, ht1, pt0, pt1, pt2, pt3, nev)
            return fly_newton(xt, ht, ht1, pt0, pt1, pt2, pt3, dlo, xt, 60, phi0, x0, v0, sa,
                              xa, va, g, gu, gd, hk, ha, th, arm, ay, av, aref, lam, om, f2,
                              htol, nev)  # fmt: skip
        if reach >= smax:
            return smax, False, nev, 0.0, 0.0, 0.0, 0.0  # (plate not evaluated at smax)
        s = reach
    p, p1, p2, p3 = plate_eval(phi0 + s, g, hk, ha, th, arm, ay, av, aref, lam, om, f2)
    return s, True, nev + 1, p, p1, p2, p3


@inlined
def contact_polish(s, h, h1, p, p1, p2, p3, nev):
    """Contact at ``s`` (``h`` within ``htol``): one Newton step of at most 1e-7 onto the root.

    Only from above the plate (``h > 0``, descending); the plate state follows by Taylor
    (dropped terms below 1e-21).  Returns the tuple of :func:`fly`.
    """
    if h1 < 0.0 and h > 0.0:
        dt = h / (-h1)
        if dt < 1e-7:
            return taylor_move(s, dt, p, p1, p2, p3, nev)
    return s, True, nev, p, p1, p2, p3


@inlined
def taylor_move(s, dt, p, p1, p2, p3, nev):
    """Move the contact by a tiny ``dt``, the plate state by Taylor; the tuple of :func:`fly`."""
    p += dt * (p1 + 0.5 * dt * p2)
    p1 += dt * (p2 + 0.5 * dt * p3)
    p2 += dt * p3
    return s + dt, True, nev, p, p1, p2, p3


@njit(cache=True, error_model="numpy")
def fly_newton(
    s, h, h1, p, p1, p2, p3, lo, hi, nmax, phi0, x0, v0, sa, xa, va, g, gu, gd, hk, ha, th,
    arm, ay, av, aref, lam, om, f2, htol, nev,
):  # fmt: skip
    """Newton steps onto the contact from ``s`` (``h``, ``h'`` and the plate known there).

    ``(lo, hi)``: a bracket of the root (a step that would leave it is replaced by
    bisection; infinite for the walk's finish).  Once ``|h| <= htol`` a last Newton step
    is taken by Taylor (no evaluation, dropped terms below 1e-21); a step below rounding
    or ``nmax`` steps also end it.  Returns the tuple of :func:`fly`.
    """
    for _ in range(nmax):
        if h1 >= 0.0:
            break  # (not inside a bracket of a decreasing h; a safety net)
        dt = h / (-h1)
        if abs(h) <= htol and abs(dt) < 1e-7:
            return taylor_move(s, dt, p, p1, p2, p3, nev)  # (either side of the root)
        sn = s + dt
        if not (lo < sn < hi) and hi - lo < math.inf:
            sn = 0.5 * (lo + hi)
        if abs(sn - s) < 1e-15 * (1.0 + s):
            break
        s = sn
        p, p1, p2, p3 = plate_eval(phi0 + s, g, hk, ha, th, arm, ay, av, aref, lam, om, f2)
        nev += 1
        xb, vb, _ = body_at(s, x0, v0, sa, xa, va, gu, gd)
        h = xb - p
        h1 = vb - p1
        if h > 0.0:
            lo = s
        else:
            hi = s
    return s, True, nev, p, p1, p2, p3


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
# Across intervals, while the body is above the plate's range (``x_body > G``), the walk
# jumps to where it comes down through ``G`` (bound 4 of ``fly``): a high flight costs no
# evaluations on the way up and over the top.
#
# The edges are placed ``SINE_EDGE`` rad early so that a takeoff exactly on the takeoff
# line (``h'' = 0`` at ``s = 0`` up to rounding) starts inside its convex interval.  In
# that sliver the wrong-signed curvature is at most ``G SINE_EDGE``, which moves any bound
# by at most ``G SINE_EDGE^2 * (interval length) < 1e-19 * 8 * 4 pi``, far below the
# contact tolerance ``htol = 1e-13``: no contact deeper than ``htol`` can be skipped.
SINE_EDGE = 1e-10


@inlined
def sine_alpha(g, c):
    """Phase ``asin(c / g)`` where ``g sin(phi) = c`` on the rising side; ``-1`` if ``g <= c``."""
    if g <= c:
        return -1.0
    return math.asin(c / g)


@inlined
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
    n = np.floor((phi - a) / TWO_PI)
    r = phi - a - n * TWO_PI  # in [0, 2 pi): phase past the convex interval's start
    w = math.pi - 2.0 * al  # convex width
    tol = 1e-13 * (1.0 + abs(phi))
    if r < w - tol:
        return True, phi + (w - r)
    if r < TWO_PI - tol:
        return False, phi + (TWO_PI - r)
    return True, phi + (TWO_PI - r) + w  # at the end of a concave interval


@inlined
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


@njit(cache=True, error_model="numpy")
def fly_sine(phi0, x0, v0, smax, g, gu, gd, al_u, al_d, htol, maxit, q0, q1, q2, q3, guess):
    """First contact after leaving ``(x0, v0)`` at ``phi0``: pure sine plate ``g sin(phi)``.

    Same contract as :func:`fly`: returns ``(s, landed, n_eval, p, p1, p2, p3)``, the
    contact is the first ``h <= htol`` with ``h' <= 0``, ``smax`` ends the search.  The
    certificates come from the curvature intervals (comment block above) instead of
    global derivative bounds.  ``al_u``, ``al_d``: :func:`sine_alpha` of ``(g, 1 + mu)`` and
    ``(g, 1 - mu)``; ``q0..q3``: the plate at ``phi0``; ``guess`` (rad, ``<= 0``: none): a
    predicted flight time (:func:`predict_flight`), used only to place trial points.

    A trial point ``x`` past the certified region is evaluated and then:
    ``h(x) <= 0`` with ``h(s) > 0`` on a convex or concave interval brackets exactly one
    crossing (the set ``h <= 0`` of a convex function is an interval; a concave
    function crosses downward once), solved by :func:`sine_bracket`; ``h(x) > 0`` clears
    ``[s, x]`` when ``h`` is concave there, or convex and still decreasing at ``x``.
    """
    sa, xa, va = body_apex(x0, v0, gu)
    split = gu != gd  # with friction the apex is a curvature edge (h'' jumps up by 2 mu)
    # the body passes below the plate's lowest point -g here: h <= 0 for certain
    s_floor = sa + (va + math.sqrt(va * va + 2.0 * gd * (xa + g))) / gd
    # ... and comes down through its highest point g here (if it rises above it at all)
    s_top = -1.0
    if xa > g:
        s_top = sa + (va + math.sqrt(va * va + 2.0 * gd * (xa - g))) / gd
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
        if s < s_top < smax and body_at(s, x0, v0, sa, xa, va, gu, gd)[0] > g:
            # above the plate's whole range (the body's height is concave in time) until
            # it comes down through g: bound 4 of fly, no evaluation on the way (not
            # past a step boundary smax: there the intervals end the flight as before)
            s = s_top
            known = False
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


@inlined
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


@njit(cache=True, error_model="numpy")
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


@njit(cache=True, error_model="numpy")
def predict_flight(hist, n, phi, v):
    """A guess of the next flight's duration (rad; 0: none) from the recent flights.

    ``hist[:n]``: takeoff phase, takeoff velocity and duration of recent flights.  The
    flight whose takeoff state was nearest (phase on the circle, velocity) is the guess:
    on a periodic orbit of period up to ``HIST`` the same takeoff recurs.  Only a trial
    point of the landing solvers: it changes how fast a landing is found, never which.
    """
    best = 0.0
    dmin = math.inf
    for j in range(n):
        d = abs(phi - hist[j, 0])
        d = min(d, TWO_PI - d) + abs(v - hist[j, 1])
        if d < dmin:
            dmin = d
            best = hist[j, 2]
    return best


@inlined
def takeoff_ok(p1, p2, gu, gd):
    """Takeoff condition of a body riding the plate: plate accelerates down faster than gravity.

    Friction makes the threshold ``1 + mu`` while the plate (and body) moves up and
    ``1 - mu`` while it moves down.
    """
    if p1 > 0.0:
        return -p2 > gu
    return -p2 > gd


#: How close (rad) to the top of the plate's cycle a takeoff under friction is taken at
#: the top (:func:`takeoff_window`): the event finder missed separations that began
#: under 5e-6 rad before it, and one 1e-4 before differs from the top's by O(1e-12).
GRAZING_TOP = 1e-4


@inlined
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
    if mu > 0.0 and HALF_PI - GRAZING_TOP < lo < HALF_PI:
        # a takeoff a hair before the top separates as the cube of the time, below the
        # event finder's tolerance, which then read a landing at once (flights of 6e-17
        # rad at Gamma 1 + mu + 1 ulp); from the top it flies what continuity says
        lo = HALF_PI + 4.5e-16
    return lo, math.pi - math.asin(gd / g)


@inlined
def ride_window(phi, phimax, lo, hi):
    """First phase ``>= phi`` inside the takeoff window ``[lo, hi)`` (mod 2 pi).

    Returns ``(phase, status)``: status 0 takeoff, 1 reached ``phimax``, 2 never (``lo < 0``).
    """
    if lo < 0.0:
        return phimax, 2
    n = np.floor(phi / TWO_PI)
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


@njit(cache=True, error_model="numpy")
def ride_general(
    phi, phimax, g, gu, gd, hk, ha, th, arm, ay, av, aref, lam, om, f2, m3, m4, maxit, rp
):  # fmt: skip
    """First phase ``>= phi`` where the takeoff condition holds, any plate (certified stepping).

    ``q = -p'' - g_eff`` must become positive.  A move by ``t`` is certified when
    ``q_down = -p'' - (1 - mu)`` cannot reach 0 (second-derivative bound ``m4``), or when
    the plate keeps moving up (``p'`` bound ``m3``) while ``q_up`` cannot reach 0.
    ``rp``: the riding body's load on the armature (:func:`plate_eval_ride`; empty: none).
    Returns ``(phase, status, p, p1, p2, p3)`` with status 0 takeoff (and the plate state
    there), 1 reached ``phimax``, 2 gave up (plate state zeros).
    """
    for _ in range(maxit):
        if phi >= phimax:
            return phimax, 1, 0.0, 0.0, 0.0, 0.0
        p, p1, p2, p3 = plate_eval_ride(phi, g, hk, ha, th, arm, ay, av, aref, lam, om, f2, rp)
        if takeoff_ok(p1, p2, gu, gd):
            return phi, 0, p, p1, p2, p3
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
    return phi, 2, 0.0, 0.0, 0.0, 0.0


@inlined
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


@njit(cache=True, error_model="numpy")
def tv_general(a, b, g, hk, ha, th, arm, ay, av, aref, lam, om, f2, m3, maxit, rp):
    """Total variation of the plate position over ``[a, b]``, stepping between zeros of ``p'``.

    A zero of ``p'`` is approached by certified steps (``m3 >= sup|p'''|``) so that no
    turning point is skipped.
    """
    phi = a
    p, p1, p2, _ = plate_eval_ride(phi, g, hk, ha, th, arm, ay, av, aref, lam, om, f2, rp)
    px = p  # the position at the last turning point
    tv = 0.0
    for _ in range(maxit):
        sg = 1.0 if p1 >= 0.0 else -1.0
        t = safe_step(sg * p1, sg * p2, m3)
        t = max(t, 1e-12 * (1.0 + abs(phi)))
        if phi + t >= b:
            break
        phi += t
        p, p1, p2, _ = plate_eval_ride(phi, g, hk, ha, th, arm, ay, av, aref, lam, om, f2, rp)
        if p1 * sg <= 1e-13:  # reached a turning point
            tv += abs(p - px)
            px = p
    pb = plate_eval_ride(b, g, hk, ha, th, arm, ay, av, aref, lam, om, f2, rp)[0]
    return tv + abs(pb - px)


@njit(cache=True, error_model="numpy")
def ride_tv(a, b, g, hk, ha, th, arm, ay, av, aref, lam, om, f2, m3, maxit, rp):
    """Path length of a body riding the plate from ``a`` to ``b``: the plate's total variation."""
    if b <= a:
        return 0.0
    if hk.shape[0] == 0 and not arm:
        return tv_sine(a, b, g)
    return tv_general(a, b, g, hk, ha, th, arm, ay, av, aref, lam, om, f2, m3, maxit, rp)


@njit(cache=True, error_model="numpy")
def emit(out, row0, rows, max_rec, row, i, n_skip, all_cols):
    """Write ``row[i]`` as the next row unless it is a skipped transient; the new row count.

    ``all_cols`` False: only :data:`FIT_COLUMNS` are written (the others keep whatever
    ``out`` held)."""
    if row[i, C_FLIGHT] >= n_skip and rows < max_rec:
        if all_cols:
            for c in range(NCOL):
                out[c, row0 + rows] = row[i, c]
        else:
            for c in FIT_COLUMNS:
                out[c, row0 + rows] = row[i, c]
        return rows + 1
    return rows


@njit(cache=True, error_model="numpy")
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
    stick_v = par[P_STICK]
    htol = par[P_HTOL]
    cap = int(par[P_CAP])
    ride_max = par[P_RIDE]
    gu = 1.0 + mu
    gd = 1.0 - mu
    use_arm = r > 0.0
    nh = hk.shape[0]
    # a riding body loads the armature (ride_load > 0): while it rides, the armature's
    # free part follows the loaded ODE (lam_r, om_r, f2_r) and rp_ride holds the forced part
    load = r * par[P_LOAD]
    ride_arm = use_arm and load > 0.0
    # The load's friction part flips sign where the plate turns.  It is not followed: at
    # low Gamma the flip itself can reverse the plate at once (stick-slip, the plate held
    # by the friction load), which needs a stick phase the model does not have (a search
    # that stopped at each turn crept for ever).  The sign at each ride's start (or Gamma
    # step) is kept (an error of order L mu in the load).
    lam_r = lam / (1.0 + load)
    f2_r = f2 / (1.0 + load)
    om_r = f2_r - lam_r * lam_r
    f_r = math.sqrt(f2_r)
    rp_none = np.zeros(0)
    rp_ride = ride_coefficients(hk, f2, lam, load) if ride_arm else rp_none
    rb2, rb3, rb4 = ride_bounds(ha, hk, rp_ride) if ride_arm else (0.0, 0.0, 0.0)
    if ride_arm:
        rl, ro, rf2, rf, rpc = lam_r, om_r, f2_r, f_r, rp_ride
    else:
        rl, ro, rf2, rf, rpc = lam, om, f2, f, rp_none
    sig = 1.0  # sign of the plate velocity where the current ride (or its step) began
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
    energy = par[P_ENERGY] > 0.0
    all_cols = par[P_ALLCOLS] > 0.0
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
    # two rows in the making: row[cur] is the flight in the air, row[rec] (while pend) a
    # landed flight whose ride is still running (its energy terms are not complete yet)
    row = np.zeros((2, NCOL))
    cur = 0
    rec = 1
    pend = False

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
    t_next = 0.0  # the next flight's duration predicted at a rebound (0: none)
    hist = np.zeros((HIST, 3))  # recent flights: takeoff phase, takeoff velocity, duration
    n_hist = 0

    while True:
        if riding:
            # ---- ride with the plate until the takeoff condition holds ----
            # energy: riding, the normal force does work [chi_p'^2/2 + chi_p] + mu TV(chi_p)
            # and friction takes mu TV(chi_p); (qa0, qa1) is the plate state at phi_e
            phi_e = phi
            if ride_arm:
                # the armature turns loaded here (free part re-referenced at phi_e)
                if arm:
                    yy, yv, _, _ = arm_eval(phi_e - aref, ay, av, lam, om, f2)
                else:  # never kicked (a start on the plate): the steady loaded ride
                    rp_ride[rp_ride.shape[0] - 1] = 0.0
                    yy, yv, _, _ = ride_particular(phi_e, g, hk, ha, th, rp_ride)
                c1, c2 = plate_eval(phi_e, g, hk, ha, th, False, 0.0, 0.0, 0.0, lam, om, f2)[1:3]
                sig = plate_direction(c1 + yv, c2)
                if not arm:
                    yy -= load * (1.0 + mu * sig) / f2  # the static part
                ay, av = ride_rebase(phi_e, yy, yv, g, hk, ha, th, rp_ride, load, f2, mu, sig)
                aref = phi_e
                arm = True
            if not qa_ok:
                qa0, qa1, _, _ = plate_eval_ride(
                    phi_e, g, hk, ha, th, arm, ay, av, aref, rl, ro, rf2, rpc
                )  # fmt: skip
            found = False
            stuck = False
            ride_from = ride_search  # the stuck limit counts from here (reset per step)
            while True:
                bound = TWO_PI * (step_end[k] - ncyc)
                lim = min(bound, ride_from + ride_max)
                if arm:
                    b0, b2, b3, b4 = arm_bounds(ay, av, rf, rl)
                else:
                    b0, b2, b3, b4 = 0.0, 0.0, 0.0, 0.0
                m3 = g * (1.0 + a3 + rb3) + b3
                m4 = g * (1.0 + a4 + rb4) + b4
                searched = False  # pb0..pb3 at the takeoff known from ride_general
                if nh == 0 and not arm:
                    if g != g_win:  # the window depends on Gamma only: computed once per step
                        lo_win, hi_win = takeoff_window(g, mu)
                        sn_win = math.sin(lo_win)
                        cs_win = math.cos(lo_win)
                        g_win = g
                    pt, st = ride_window(ride_search, lim, lo_win, hi_win)
                elif g * (1.0 + a2 + rb2) + b2 <= gd:
                    pt, st = lim, 2  # the plate can never out-accelerate gravity
                else:
                    pt, st, pb0, pb1, pb2, pb3 = ride_general(
                        ride_search, lim, g, gu, gd, hk, ha, th, arm, ay, av, aref,
                        rl, ro, rf2, m3, m4, maxit, rpc,
                    )  # fmt: skip
                    searched = st == 0
                if st != 0 and pt < bound and k < nsteps - 1:
                    pt = bound  # no takeoff at this Gamma: the body rides on to the next step
                if searched:
                    pass  # the search evaluated the plate at the takeoff
                elif fast and st == 0 and qa_ok and pt == phi_e:
                    # takes off where it landed: the plate state is the contact's
                    pb0, pb1, pb2, pb3 = qa0, qa1, qa2, qa3
                elif fast and st == 0 and pt != ride_search:
                    # a window start lo + 2 pi n: the plate there in closed form
                    pb0, pb1, pb2, pb3 = g * sn_win, g * cs_win, -g * sn_win, -g * cs_win
                else:
                    pb0, pb1, pb2, pb3 = plate_eval_ride(
                        pt, g, hk, ha, th, arm, ay, av, aref, rl, ro, rf2, rpc
                    )  # fmt: skip
                if pend:
                    fr_ = 0.0
                    # the ride's path length only feeds the energy columns; on a plate that
                    # is not a pure sine it costs a certified walk between turning points
                    if mu > 0.0 and energy:
                        fr_ = mu * ride_tv(
                            phi_e, pt, g, hk, ha, th, arm, ay, av, aref, rl, ro, rf2, m3, maxit,
                            rpc,
                        )  # fmt: skip
                    row[rec, C_EPLATE] += 0.5 * (pb1 * pb1 - qa1 * qa1) + (pb0 - qa0) + fr_
                    row[rec, C_EFRIC] += fr_
                phi_e = pt
                qa0 = pb0
                qa1 = pb1
                if st == 0:
                    phi = pt
                    found = True
                    if ride_arm:  # unloaded from here: the free armature from its state
                        yy, yv = ride_armature(pt, g, hk, ha, th, ay, av, aref, rl, ro, rf2, rpc)
                        ay = yy
                        av = yv
                        aref = pt
                        pb0, pb1, pb2, pb3 = plate_eval(
                            pt, g, hk, ha, th, arm, ay, av, aref, lam, om, f2
                        )  # fmt: skip
                        qa0 = pb0
                        qa1 = pb1
                    tq0, tq1, tq2, tq3 = pb0, pb1, pb2, pb3  # plate at the takeoff
                    tq_ok = True
                    break
                if k == nsteps - 1:
                    stuck = pt < bound
                    break  # stuck for good, or the protocol ends during the ride
                # step boundary: the plate switches amplitude under the riding body
                if ride_arm:
                    yy, yv = ride_armature(bound, g, hk, ha, th, ay, av, aref, rl, ro, rf2, rpc)
                k += 1
                g = g_true[k]
                if ride_arm:  # the forced part changes with Gamma: re-reference the free part
                    c1, c2 = plate_eval(bound, g, hk, ha, th, False, 0.0, 0.0, 0.0, lam, om, f2)[
                        1:3
                    ]
                    sig = plate_direction(c1 + yv, c2)
                    ay, av = ride_rebase(bound, yy, yv, g, hk, ha, th, rp_ride, load, f2, mu, sig)
                    aref = bound
                pb0, pb1, _, _ = plate_eval_ride(
                    bound, g, hk, ha, th, arm, ay, av, aref, rl, ro, rf2, rpc
                )  # fmt: skip
                if pend:  # the plate's jump in velocity (and position) is work on the body
                    row[rec, C_EPLATE] += 0.5 * (pb1 * pb1 - qa1 * qa1) + (pb0 - qa0)
                qa0 = pb0
                qa1 = pb1
                phi_e = bound
                ride_search = bound
                ride_from = bound
            if not found:
                if pend and stuck:
                    # the last flight's ride never ends: energy counted to the give-up point
                    rows = emit(out, row0, rows, max_rec, row, rec, n_skip, all_cols)
                return rows, ST_STUCK if stuck else ST_END
            x0 = qa0
            v0 = qa1
            chatter = False
            riding = False

        # ---- flight ----
        # move the frame so that 0 <= phi < 2 pi (harmonic offsets and armature follow)
        if phi >= TWO_PI or phi < 0.0:
            nn = np.floor(phi / TWO_PI)
            phi -= nn * TWO_PI
            ncyc += int(nn)
            for j in range(nh):
                kn = hk[j] * nn
                th[j] = (th[j] + TWO_PI * (kn - math.floor(kn))) % TWO_PI
            aref -= nn * TWO_PI
        row[cur, C_EFRIC] = 0.0
        row[cur, C_EPLATE] = 0.0
        row[cur, C_CHAT] = 0.0
        row[cur, C_TAIL] = 0.0
        row[cur, C_GAMMA] = g_stated[k]
        row[cur, C_PHI0] = phi
        row[cur, C_START] = start_id
        row[cur, C_STEP] = k
        tto = TWO_PI * ncyc + phi
        step_start = step_end[k - 1] if k > 0 else 0
        row[cur, C_TTO] = tto
        row[cur, C_SETTLED] = 1.0 if tto >= TWO_PI * (step_start + settle) - 1e-9 else 0.0
        row[cur, C_X0] = x0
        row[cur, C_V0] = v0
        row[cur, C_FLIGHT] = n_fl

        if arm:
            b0, b2, b3, b4 = arm_bounds(ay, av, f, lam)
        else:
            b0, b2, b3, b4 = 0.0, 0.0, 0.0, 0.0
        phis = phi  # segment start (a flight may cross step boundaries)
        # the landing search's trial point: after a rebound in the sticking region the
        # chatter prediction, else the duration of the recent flight with the nearest takeoff
        guess = t_next if t_next > 0.0 else predict_flight(hist, min(n_hist, HIST), phi, v0)
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
                    tq0, tq1, tq2, tq3, guess,
                )  # fmt: skip
            else:
                s, landed, nit, p, p1, p2, p3 = fly(
                    phis, x0, v0, bound - phis, g, gu, gd, hk, ha, th, arm, ay, av, aref,
                    lam, om, f2, m2, m3, m4, pmax, htol, maxit, tq0, tq1, tq2, tq3,
                    guess if phis == phi else 0.0,
                )  # fmt: skip
            tq_ok = False
            nit_tot += nit
            if mu > 0.0:
                row[cur, C_EFRIC] += mu * path_length(s, x0, v0, gu, gd)
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
                rows = emit(out, row0, rows, max_rec, row, rec, n_skip, all_cols)
            return rows, ST_END
        if total == 0.0 and k == k_to:
            # no real flight (a touch of the takeoff line without crossing it): ride on
            riding = True
            qa_ok = False
            ride_search = phi + 1e-9
            continue
        if pend:
            rows = emit(out, row0, rows, max_rec, row, rec, n_skip, all_cols)
            pend = False
            if rows >= max_rec:
                return rows, ST_FULL
        n_fl += 1
        phil = phis + s
        row[cur, C_T] = total
        if k != k_to and s <= CAUGHT:
            # caught by the change of Gamma itself: the instant amplitude change jumps the
            # plate's velocity (by Delta Gamma), which catches a body that took off just
            # before it, a flight no real (or ramped) drive makes. Not compared.
            row[cur, C_SETTLED] = 0.0
        row[cur, C_PHIL] = mod_two_pi(phil)
        # chatter: a rebound from the sticking region shorter than the flight before it,
        # i.e. part of a decaying sequence of impacts heading for sticking
        if chatter and total < t_prev:
            row[cur, C_CHAT] = 1.0
            n_imp += 1
        else:
            n_imp = 0
        t_prev = total
        t_next = 0.0
        hist[n_hist % HIST, 0] = row[cur, C_PHI0]
        hist[n_hist % HIST, 1] = row[cur, C_V0]
        hist[n_hist % HIST, 2] = total
        n_hist += 1
        row[cur, C_NSTEPS] = nit_tot

        # ---- impact ---- (p, p1, p2: the plate at the contact, from fly)
        xb, vb, _ = body_eval(s, x0, v0, gu, gd)
        u = min(vb - p1, 0.0)
        row[cur, C_VIMP] = u
        stick_here = not takeoff_ok(p1, p2, gu, gd)
        # does the chatter end here?  Predict the next micro-flight with the plate's
        # acceleration frozen: the body rises with relative deceleration c1, falls with c2.
        w = -e * u
        tau = 0.0
        eff_e = e
        if 0.0 < w < stick_v:
            # slower than the sticking speed: the body stays on the plate (no tail: its
            # impacts end here, as a real body's do where they get slow)
            eff_e = 0.0
        elif w > 0.0:
            c1 = (gu if p1 + w > 0.0 else gd) + p2
            c2 = (gu if p1 > 0.0 else gd) + p2
            if c1 > 0.0 and c2 > 0.0:
                tm = w / c1 + w / math.sqrt(c1 * c2)
                t_next = tm  # a rebound in the sticking region: the next flight is short
                rho = e * math.sqrt(c2 / c1)
                if (tm < eps_t or n_imp >= cap) and rho < 1.0:
                    eff_e = 0.0
                    tau = tm / (1.0 - rho)  # the summed geometric tail of micro-flights
                    row[cur, C_TAIL] = tau
        jmp = (1.0 + eff_e) * (-u) / (1.0 + r)  # body velocity change (two-body impact)
        row[cur, C_EIMP] = (1.0 - eff_e * eff_e) * u * u / (2.0 * (1.0 + r))
        row[cur, C_EPLATE] += jmp * p1 - r * jmp * jmp / 2.0
        if use_arm:
            # re-reference the armature at the impact; it recoils by -r * jmp, which
            # changes the plate's velocity (and, by its ODE, higher derivatives) at once
            p, p1, p2, p3 = armature_kick(p, p1, p2, p3, -r * jmp, lam, f2)
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
            tq0, tq1, tq2, tq3 = p, p1, p2, p3  # the plate at the next takeoff
            tq_ok = True
            rows = emit(out, row0, rows, max_rec, row, cur, n_skip, all_cols)
            if rows >= max_rec:
                return rows, ST_FULL
            continue
        # inelastic (or the chatter tail summed): the body rides from here
        qa_ok = True
        qa0 = p
        qa1 = p1
        qa2 = p2
        qa3 = p3
        cur, rec = rec, cur  # this row waits for its ride; the next flight gets the other
        pend = True
        riding = True
        ride_search = phil + tau


@njit(cache=True, error_model="numpy")
def spread_stride(n):
    """A stride coprime to ``n`` near ``0.618 n``: ``i -> i * stride mod n`` is a permutation.

    prange hands each thread a contiguous block of iterations; through this permutation
    every block holds trajectories spread evenly over the whole input (golden-ratio
    sequence), so threads get equal work when the cost varies along the input (e.g. a
    Gamma grid, where high Gammas cost more per flight).
    """
    st = max(int(0.6180339887498949 * n), 1)
    while math.gcd(st, n) != 1:
        st -= 1
    return st


@njit(cache=True, parallel=True, error_model="numpy")
def run_many(
    par, hk, ha, hpsi, g_true, g_stated, step_end, init_ride, phi_init, x_init, v_init,
    n_skip, max_rec, settle, start_id, out,
):  # fmt: skip
    """Independent trajectories in parallel: row ``i`` of ``g_true`` etc. is trajectory ``i``.

    ``g_true``, ``g_stated``: ``(n_traj, n_steps)``; ``step_end``: ``(n_steps,)``;
    ``phi_init``, ``x_init``, ``v_init``, ``start_id``: ``(n_traj,)``;
    ``out``: ``(NCOL, n_traj * max_rec)`` (one contiguous row per column).
    Returns ``(rows, status)``, arrays of shape ``(n_traj,)``.  Trajectories are handed
    out in a spread order (:func:`spread_stride`) so that threads share costly and cheap
    ones alike; each result depends only on its own trajectory's inputs.
    """
    n = g_true.shape[0]
    rows = np.zeros(n, dtype=np.int64)
    status = np.zeros(n, dtype=np.int64)
    stride = spread_stride(n)
    for i0 in prange(n):
        i = (i0 * stride) % n  # a permutation of 0..n-1
        rw, st = trajectory(
            par, hk, ha, hpsi, g_true[i], g_stated[i], step_end, init_ride, phi_init[i],
            x_init[i], v_init[i], n_skip, max_rec, settle, start_id[i], out, i * max_rec,
        )  # fmt: skip
        rows[i] = rw
        status[i] = st
    return rows, status


@njit(cache=True, error_model="numpy")
def circuit_opens(t_takeoff, T, last_landing, min_contact):
    """Where the continuity circuit opens for a flight, and its landing (both rad).

    The circuit opens at ``max(takeoff, previous landing + min_contact)``; the flight is
    seen when that is before its landing. One place for the rule of
    :func:`close_contacts` and :func:`protocol_rows`.
    """
    return max(t_takeoff, last_landing + min_contact), t_takeoff + T


@njit(cache=True, error_model="numpy")
def close_contacts(member, t_takeoff, T, min_contact):
    """The flights a continuity circuit shows when each contact lasts at least ``min_contact``.

    A real body is in contact for a finite time at every impact (tens to hundreds of
    microseconds), which the model's instantaneous impacts lack; the circuit opens at
    ``max(takeoff, previous landing + min_contact)``, and a flight that lands before it
    would open is not seen at all (its contact runs on). ``member`` (n,) int, flights in
    time order within each member; ``t_takeoff`` (n,) absolute takeoff phase, ``T`` (n,)
    flight time, ``min_contact`` >= 0, all rad. Returns ``(seen, t_open, T_seen)``,
    shape (n,): bool, the circuit's opening phase and the flight time it shows.
    """
    n = T.shape[0]
    seen = np.zeros(n, dtype=np.bool_)
    t_open = t_takeoff.copy()
    T_seen = T.copy()
    last_member = -1
    last_landing = -np.inf
    for i in range(n):
        if member[i] != last_member:
            last_member = member[i]
            last_landing = -np.inf
        opens, landing = circuit_opens(t_takeoff[i], T[i], last_landing, min_contact)
        if opens < landing:
            seen[i] = True
            t_open[i] = opens
            T_seen[i] = landing - opens
        last_landing = landing
    return seen, t_open, T_seen


@njit(cache=True, error_model="numpy")
def protocol_rows(out, rows, max_rec, min_contact):
    """Member, step, flight time and settled flag of the rows :func:`run_many` wrote.

    ``out`` (NCOL, n_traj * max_rec): trajectory ``i``'s ``rows[i]`` rows start at
    ``i * max_rec``. With ``min_contact > 0`` (rad) only the flights a continuity circuit
    shows, with the times it shows (:func:`close_contacts`, member by member). One pass
    instead of gathering each column out of the buffer and filtering it again: that was
    a tenth of a fit's evaluation, spent on one core. Returns ``(member, step, T,
    settled)``: int64, int64, float64 (rad) and bool arrays of one length, in time order
    within each trajectory. Reads :data:`FIT_COLUMNS` only.
    """
    n_all = rows.sum()
    member = np.empty(n_all, dtype=np.int64)
    step = np.empty(n_all, dtype=np.int64)
    T = np.empty(n_all)
    settled = np.empty(n_all, dtype=np.bool_)
    m = 0
    for b in range(rows.shape[0]):
        last_landing = -np.inf  # each trajectory is one member: the circuit starts afresh
        for i in range(b * max_rec, b * max_rec + rows[b]):
            t = out[C_T, i]
            if min_contact > 0.0:
                opens, landing = circuit_opens(out[C_TTO, i], t, last_landing, min_contact)
                last_landing = landing
                if not opens < landing:
                    continue
                t = landing - opens
            member[m] = np.int64(out[C_START, i])
            step[m] = np.int64(out[C_STEP, i])
            T[m] = t
            settled[m] = out[C_SETTLED, i] > 0.5
            m += 1
    return member[:m], step[:m], T[:m], settled[:m]
