"""The rig's numba kernels: the time-stepped, dimensional (SI) physics of the lab.

Everything here is a small ``@njit(cache=True)`` function on scalars and flat arrays; the
configuration, the random draws and the writing live elsewhere (``config.py``,
``simulate.py``, ``sensors.py``). Heights are of the mass's bottom face and of the
plate's top face, in metres, upward positive, zero at the plate's rest position.

The parameters travel as one float64 vector ``p`` indexed by the ``P_*`` constants below
(numba reads module-level integers as compile-time constants), the integrator state as
one float64 vector ``s`` indexed by the ``S_*`` constants, so a recording can be
simulated chunk by chunk with the state carried over.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

# --- parameter vector p -------------------------------------------------------------
P_MASS = 0  # kg, the bouncing body
P_G = 1  # m/s^2
P_MU = 2  # Coulomb friction force on the guide, fraction of the weight
P_V_REG = 3  # m/s, friction regularisation speed (see body_force)
P_DRAG = 4  # N s/m, viscous air drag on the body (optional effect)
P_K = 5  # N/m, contact stiffness
P_MU_RED = 6  # kg, reduced mass of the contact (body and armature)
P_E0 = 7  # restitution at the reference impact speed
P_E_SLOPE = 8  # s/m, d e / d |u| (velocity-dependent restitution, optional effect)
P_U_REF = 9  # m/s, reference impact speed of P_E0
P_OMEGA = 10  # rad/s, drive angular frequency
P_RAMP = 11  # s, duration of the linear amplitude ramp at each step start
P_FEEDBACK = 12  # 1.0: the armature moves under the contact force, 0.0: rigid shaker
P_ARM_MASS = 13  # kg, armature + plate
P_ARM_K = 14  # N/m, armature suspension stiffness
P_ARM_C = 15  # N s/m, armature damping
P_RELEASE_T = 16  # s, drop tests: the body is held still until this time
P_HOLD_X = 17  # m, drop tests: height of the held body
P_RC_TAU = 18  # s, time constant of the continuity circuit's RC front end
P_FS = 19  # Hz, ADC sample rate
P_NSUB = 20  # integration steps per ADC sample while in contact
P_NCOARSE = 21  # integration steps per ADC sample in flight
P_NREST = 22  # integration steps per ADC sample in a contact older than P_FINE_WINDOW
P_FINE_WINDOW = 23  # s, how long after a landing the fine step P_NSUB is kept
N_PARAMS = 24

# --- state vector s ---------------------------------------------------------------------
S_X = 0  # m, body height
S_V = 1  # m/s, body velocity
S_Y = 2  # m, armature displacement from its unloaded rest
S_W = 3  # m/s, armature velocity
S_AM = 4  # m/s^2, body acceleration at the current time (velocity Verlet carries it)
S_AY = 5  # m/s^2, armature acceleration at the current time
S_RC = 6  # RC front-end output, 0 (contact) .. 1 (open), normalised
S_CONTACT = 7  # 1.0 while the penetration is > 0
S_C = 8  # N s/m, dashpot constant of the current contact
S_DELTA = 9  # m, penetration at the current time (plate surface minus body bottom)
S_SEG = 10  # index of the current Gamma step segment
S_TLAND = 11  # s, time of the last landing
S_DDELTA = 12  # m/s, rate of the penetration at the current time (> 0: approaching)
N_STATE = 13

EV_LANDING = 1
EDGE_ITER = 12  # regula falsi iterations at most, to find a contact edge
MAX_EDGES_PER_SAMPLE = 64  # beyond this an edge is taken without cutting the step
EDGE_TOL = 1e-13  # m, penetration residual accepted at an edge (k * tol << weight)
EV_TAKEOFF = -1


@njit(cache=True)
def zeta_from_restitution(e):
    """Damping ratio of a linear spring-dashpot contact that restitutes ``e``.

    A linear contact ``mu_red d'' + c d' + k d = 0`` entered with speed u leaves when the
    penetration ``d`` returns to zero, after half a damped period, with speed
    ``u exp(-pi zeta / sqrt(1 - zeta^2))``; inverting gives
    ``zeta = -ln e / sqrt(pi^2 + ln^2 e)``. ``e <= 0`` gives critical damping
    (``zeta = 1``): the penetration never returns to zero by itself, the body does not
    rebound (the plastic mode).
    """
    if e <= 0.0:
        return 1.0
    le = math.log(e)
    return -le / math.sqrt(math.pi * math.pi + le * le)


@njit(cache=True)
def dashpot(p, e):
    """Dashpot constant (N s/m) ``c = 2 zeta(e) sqrt(k mu_red)`` for restitution ``e``."""
    return 2.0 * zeta_from_restitution(e) * math.sqrt(p[P_K] * p[P_MU_RED])


@njit(cache=True)
def restitution_at(p, u):
    """Restitution for an impact at relative speed ``|u|`` (m/s), clipped to [0, 0.99].

    Constant ``P_E0`` unless the optional velocity-dependent effect sets ``P_E_SLOPE``:
    ``e(u) = e0 + slope (|u| - u_ref)``.
    """
    e = p[P_E0] + p[P_E_SLOPE] * (abs(u) - p[P_U_REF])
    return min(max(e, 0.0), 0.99)


@njit(cache=True)
def amplitude(t, seg, seg_t, seg_amp, seg_prev, ramp):
    """True plate amplitude (m) and its rate (m/s) at time ``t`` (s).

    Segment ``seg`` starts at ``seg_t[seg]``; its amplitude goes linearly from
    ``seg_prev[seg]`` to ``seg_amp[seg]`` over ``ramp`` seconds so the plate's position
    and velocity stay continuous when a step starts at phase zero.
    Returns ``(A, dA/dt, seg)`` with ``seg`` advanced past every segment started by ``t``.
    """
    while seg + 1 < seg_t.size and t >= seg_t[seg + 1]:
        seg += 1
    r = (t - seg_t[seg]) / ramp if ramp > 0.0 else 1.0
    if r >= 1.0:
        return seg_amp[seg], 0.0, seg
    if r < 0.0:
        r = 0.0
    da = seg_amp[seg] - seg_prev[seg]
    return seg_prev[seg] + da * r, da / ramp, seg


@njit(cache=True)
def plate_command(t, a, da, omega, hk, ha, hpsi):
    """Commanded plate motion ``A(t) [sin(w t) + sum_j a_j sin(k_j w t + psi_j)]``.

    ``a``, ``da``: amplitude (m) and its rate (m/s); ``hk``, ``ha``, ``hpsi`` (n_harm,):
    harmonic multiples (non-integer allowed), relative amplitudes, phases (rad).
    Returns position (m), velocity (m/s), acceleration (m/s^2); the ramp's own
    curvature is zero (linear ramp).
    """
    if a == 0.0 and da == 0.0:
        return 0.0, 0.0, 0.0  # plate still (drop tests, Gamma = 0): skip the sines
    ph = omega * t
    sn = math.sin(ph)
    cs = math.cos(ph)
    s0 = sn
    s1 = omega * cs
    s2 = -omega * omega * sn
    for j in range(hk.size):
        wk = hk[j] * omega
        phj = hk[j] * ph + hpsi[j]
        sj = math.sin(phj)
        s0 += ha[j] * sj
        s1 += ha[j] * wk * math.cos(phj)
        s2 -= ha[j] * wk * wk * sj
    return a * s0, da * s0 + a * s1, 2.0 * da * s1 + a * s2


@njit(cache=True)
def body_force(p, v, contact_force):
    """Net force (N) on the body: contact, gravity, regularised Coulomb friction, drag.

    Friction is fixed in the lab frame (the guide pole):
    ``-mu m g v / sqrt(v^2 + v_reg^2)``, smooth through ``v = 0`` so the integrator stays
    stable (an algebraic sigmoid: cheaper than ``tanh`` and as good).
    """
    m = p[P_MASS]
    w = m * p[P_G]
    vr = p[P_V_REG]
    return contact_force - w - p[P_MU] * w * v / math.sqrt(v * v + vr * vr) - p[P_DRAG] * v


@njit(cache=True)
def interp_sample(arr, i, frac):
    """Value of the per-sample array ``arr`` at ``frac`` (0..1) of the way from i to i+1."""
    return arr[i] + frac * (arr[i + 1] - arr[i])


@njit(cache=True)
def accelerations(p, x, v, y, w, t, law_contact, c, xc, vc, xr, vr):
    """Body and armature accelerations under a given contact law, and their Jacobian.

    ``law_contact`` chooses the force law (spring-dashpot ``k delta + c delta'``, or
    none) independently of the sign of ``delta``, so a step can be integrated up to a
    contact edge under the law that held before it. ``xc``, ``vc``: commanded plate
    position and velocity; ``xr``, ``vr``: random plate vibration (m, m/s).

    Returns ``(a_body, a_arm, j_bb, j_ba, j_ab, j_aa, delta, ddelta, f_contact)``:
    accelerations (m/s^2), their derivatives with respect to the body and armature
    velocities (1/s), the penetration (m), its rate (m/s, > 0: approaching) and the
    contact force on the body (N).
    """
    m = p[P_MASS]
    delta = xc + y + xr - x
    ddelta = vc + w + vr - v
    cc = c if law_contact else 0.0
    fc = p[P_K] * delta + cc * ddelta if law_contact else 0.0
    if t < p[P_RELEASE_T]:  # drop test: the body is held still
        am, j_bb, j_ba = 0.0, 0.0, 0.0
    else:
        am = body_force(p, v, fc) / m
        vreg = p[P_V_REG]
        q = 1.0 / math.sqrt(v * v + vreg * vreg)
        dfric = p[P_MU] * p[P_G] * vreg * vreg * q * q * q  # d(friction acc)/dv
        j_bb = -cc / m - dfric - p[P_DRAG] / m
        j_ba = cc / m
    ay, j_ab, j_aa = 0.0, 0.0, 0.0
    if p[P_FEEDBACK] > 0.5:
        arm_m = p[P_ARM_MASS]
        ay = (-p[P_ARM_K] * y - p[P_ARM_C] * w - fc) / arm_m
        j_ab = cc / arm_m
        j_aa = -(p[P_ARM_C] + cc) / arm_m
    return am, ay, j_bb, j_ba, j_ab, j_aa, delta, ddelta, fc


@njit(cache=True)
def step(p, x, v, y, w, am, ay, t, h, law, c, xc, vc, xr, vr):
    """One step of length ``h`` (s) from ``t`` under a fixed contact law.

    Velocity Verlet for the positions; the closing velocity half-kick is implicit
    (trapezoidal) in the velocity-dependent forces, linearised once around the
    explicit prediction: the dashpot and drag are linear so this is exact for them, and
    the stiff friction regularisation near ``v = 0`` stays stable. ``xc``, ``vc``,
    ``xr``, ``vr``: plate command and vibration at ``t + h``.

    Returns ``(x, v, y, w, am, ay, delta, ddelta, fc)`` at ``t + h``.
    """
    held = t + h < p[P_RELEASE_T]
    vh = v + 0.5 * h * am
    wh = w + 0.5 * h * ay
    if held:
        x = p[P_HOLD_X]
        vh = 0.0
    else:
        x += h * vh
    y += h * wh
    vp = vh + 0.5 * h * am
    wp = wh + 0.5 * h * ay
    am, ay, jbb, jba, jab, jaa, delta, ddelta, fc = accelerations(
        p, x, vp, y, wp, t + h, law, c, xc, vc, xr, vr
    )
    # solve (I - h/2 J) dv = (vh + h/2 a(vp)) - vp for the correction dv = v_new - vp
    hh = 0.5 * h
    r1 = vh + hh * am - vp
    r2 = wh + hh * ay - wp
    a11 = 1.0 - hh * jbb
    a12 = -hh * jba
    a21 = -hh * jab
    a22 = 1.0 - hh * jaa
    det = a11 * a22 - a12 * a21
    d1 = (r1 * a22 - a12 * r2) / det
    d2 = (a11 * r2 - a21 * r1) / det
    v = 0.0 if held else vp + d1
    w = wp + d2
    am += jbb * d1 + jba * d2
    ay += jab * d1 + jaa * d2
    ddelta -= d1 - d2
    if law:
        fc += c * (d2 - d1)
    return x, v, y, w, am, ay, delta, ddelta, fc


@njit(cache=True)
def plate_at(p, t, seg, seg_t, seg_amp, seg_prev, hk, ha, hpsi):
    """Commanded plate position (m), velocity (m/s), acceleration (m/s^2) at ``t`` (s).

    Returns ``(x, v, a, seg)`` with the step segment index advanced to ``t``.
    """
    a_amp, a_rate, seg = amplitude(t, seg, seg_t, seg_amp, seg_prev, p[P_RAMP])
    xc, vc, ac = plate_command(t, a_amp, a_rate, p[P_OMEGA], hk, ha, hpsi)
    return xc, vc, ac, seg


@njit(cache=True)
def simulate_chunk(
    p, s, i0, n, seg_t, seg_amp, seg_prev, hk, ha, hpsi, rnd_x, rnd_v, rnd_a,
    out_rc, out_acc, out_force, ev_t, ev_kind, ev_v,
):  # fmt: skip
    """Advance the rig over ADC samples ``i0 .. i0+n-1``.

    Within a sample period the step is ``1 / (fs * P_NSUB)`` for ``P_FINE_WINDOW``
    seconds after a landing (the impact: the stiff contact needs it), ``1 / (fs *
    P_NREST)`` in a longer contact (the body rides the plate, quasi-static on the
    spring) and ``1 / (fs * P_NCOARSE)`` in flight. A step in
    which the penetration changes sign is cut at the edge, found to ``EDGE_TOL`` by
    regula falsi (Illinois) on the step length; the forces are re-evaluated under the
    new law there. Without the cut the dashpot's jump at the edges costs an error of
    first order in the step (per cent in the restitution).

    Parameters
    ----------
    p : (N_PARAMS,) float64, the ``P_*`` parameters.
    s : (N_STATE,) float64, the ``S_*`` state at time ``i0 / fs``; updated in place to
        the state at ``(i0 + n) / fs``.
    seg_t, seg_amp, seg_prev : (n_seg,) step start times (s), true amplitudes (m) and the
        amplitude each ramps from (m).
    hk, ha, hpsi : (n_harm,) harmonic distortion of the drive.
    rnd_x, rnd_v, rnd_a : (n + 1,) random plate vibration at the sample instants
        (m, m/s, m/s^2), linearly interpolated between them; zeros when off.
    out_rc, out_acc, out_force : (n,) outputs at each sample: the RC front-end output at
        the sample instant (0 contact .. 1 open), the plate acceleration at the sample
        instant (m/s^2) and the contact force averaged over the sample period (N).
    ev_t, ev_kind, ev_v : (m,) event buffers: edge time (s), ``EV_LANDING`` or
        ``EV_TAKEOFF``, relative velocity body minus plate (m/s, negative = approaching).

    Returns
    -------
    int : events written; ``-1`` if the buffers overflowed.
    """
    fs = p[P_FS]
    ts = 1.0 / fs
    h_fine = ts / p[P_NSUB]
    h_coarse = ts / p[P_NCOARSE]
    h_rest = ts / p[P_NREST]
    fine_window = p[P_FINE_WINDOW]
    tau = p[P_RC_TAU]
    alpha_fine = 1.0 - math.exp(-h_fine / tau)
    alpha_coarse = 1.0 - math.exp(-h_coarse / tau)
    alpha_rest = 1.0 - math.exp(-h_rest / tau)

    x, v, y, w = s[S_X], s[S_V], s[S_Y], s[S_W]
    am, ay, rc, c = s[S_AM], s[S_AY], s[S_RC], s[S_C]
    contact = s[S_CONTACT] > 0.5
    delta, ddelta = s[S_DELTA], s[S_DDELTA]
    seg = int(s[S_SEG])
    t_land = s[S_TLAND]
    fc = p[P_K] * delta if contact else 0.0
    n_ev = 0
    overflow = False

    for i in range(n):
        t0 = (i0 + i) * ts
        _, _, ac, seg = plate_at(p, t0, seg, seg_t, seg_amp, seg_prev, hk, ha, hpsi)
        out_rc[i] = rc
        out_acc[i] = ac + ay + rnd_a[i]
        impulse = 0.0
        u = 0.0  # time into the sample period, s
        n_edges = 0  # a guard: zero-length edge pairs must not stall the loop
        while u < ts * (1.0 - 1e-9):
            t = t0 + u
            if not contact:
                h = h_coarse
            elif t - t_land < fine_window:
                h = h_fine
            else:
                h = h_rest
            h = min(h, ts - u)
            xc, vc, _, seg = plate_at(p, t + h, seg, seg_t, seg_amp, seg_prev, hk, ha, hpsi)
            xr = interp_sample(rnd_x, i, (u + h) * fs)
            vr = interp_sample(rnd_v, i, (u + h) * fs)
            st = step(p, x, v, y, w, am, ay, t, h, contact, c, xc, vc, xr, vr)
            if (st[6] > 0.0) != contact and n_edges < MAX_EDGES_PER_SAMPLE:
                n_edges += 1
                # an edge inside the step: shorten the step to end on it
                lo, d_lo, hi, d_hi = 0.0, delta, h, st[6]
                side = 0
                # the edge just before left a residual |delta| < EDGE_TOL that may sit on
                # the far side of zero: then this step starts on the edge (h1 = 0)
                n_iter = EDGE_ITER if (d_lo > 0.0) != (d_hi > 0.0) else 0
                h1 = 0.0
                if n_iter == 0:
                    st = (x, v, y, w, am, ay, delta, ddelta, fc)
                for _ in range(n_iter):
                    h1 = lo + (hi - lo) * d_lo / (d_lo - d_hi)
                    xc, vc, _, seg = plate_at(
                        p, t + h1, seg, seg_t, seg_amp, seg_prev, hk, ha, hpsi
                    )
                    xr = interp_sample(rnd_x, i, (u + h1) * fs)
                    vr = interp_sample(rnd_v, i, (u + h1) * fs)
                    st = step(p, x, v, y, w, am, ay, t, h1, contact, c, xc, vc, xr, vr)
                    d1 = st[6]
                    if abs(d1) < EDGE_TOL:
                        break
                    if (d1 > 0.0) == (d_lo > 0.0):
                        lo, d_lo = h1, d1
                        if side == -1:
                            d_hi *= 0.5  # Illinois: keep the stale end from stalling
                        side = -1
                    else:
                        hi, d_hi = h1, d1
                        if side == 1:
                            d_lo *= 0.5
                        side = 1
                h = h1
                xc, vc, _, seg = plate_at(p, t + h, seg, seg_t, seg_amp, seg_prev, hk, ha, hpsi)
                xr = interp_sample(rnd_x, i, (u + h) * fs)
                vr = interp_sample(rnd_v, i, (u + h) * fs)
                f_old = fc
                x, v, y, w, am, ay, delta, ddelta, fc = st
                impulse += 0.5 * (f_old + fc) * h
                contact = not contact
                if n_ev < ev_t.size:
                    ev_t[n_ev] = t + h
                    ev_kind[n_ev] = EV_LANDING if contact else EV_TAKEOFF
                    ev_v[n_ev] = -ddelta
                    n_ev += 1
                else:
                    overflow = True
                if contact:
                    c = dashpot(p, restitution_at(p, ddelta))
                    t_land = t + h
                am, ay, _, _, _, _, delta, ddelta, fc = accelerations(
                    p, x, v, y, w, t + h, contact, c, xc, vc, xr, vr
                )
                # the step ran under the old state: open while the new one is contact
                rc += ((1.0 if contact else 0.0) - rc) * (1.0 - math.exp(-h / tau))
            else:
                f_old = fc
                x, v, y, w, am, ay, delta, ddelta, fc = st
                contact = delta > 0.0  # changes only past the guard (no event then)
                impulse += 0.5 * (f_old + fc) * h
                if h == h_fine:
                    alpha = alpha_fine
                elif h == h_coarse:
                    alpha = alpha_coarse
                elif h == h_rest:
                    alpha = alpha_rest
                else:
                    alpha = 1.0 - math.exp(-h / tau)
                rc += ((0.0 if contact else 1.0) - rc) * alpha  # exact RC update over h
            u += h
        out_force[i] = impulse * fs

    s[S_X], s[S_V], s[S_Y], s[S_W] = x, v, y, w
    s[S_AM], s[S_AY], s[S_RC], s[S_C] = am, ay, rc, c
    s[S_CONTACT] = 1.0 if contact else 0.0
    s[S_DELTA], s[S_DDELTA] = delta, ddelta
    s[S_SEG] = seg
    s[S_TLAND] = t_land
    return -1 if overflow else n_ev


def new_params() -> np.ndarray:
    """A zeroed parameter vector of the right length (fill it by the ``P_*`` names)."""
    return np.zeros(N_PARAMS)


def new_state() -> np.ndarray:
    """A zeroed state vector of the right length (fill it by the ``S_*`` names)."""
    return np.zeros(N_STATE)
