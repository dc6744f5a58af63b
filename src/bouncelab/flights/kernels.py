"""Numba kernels of the continuity detection: block levels, RC constant, edges.

Each kernel is one pass over a 1-D float array of samples and keeps O(1) state besides
its (small) outputs, so a 20-minute recording needs nothing beyond the samples.
Time is in samples here (sample ``k`` is at ``t = k``); the Python side converts.

Two sets: the ``*_serial`` kernels define the results (one thread, one pass each); the
fast kernels below them (``levels_run``/``levels_walk``, ``rc_range``, ``edge_range``,
``place_pulses``) work on pieces of the recording that can run on several threads
(they release the GIL) and give the same numbers bit for bit once the pieces are
stitched (``bouncelab.flights.detect.Parallel``; tests/flights/test_parallel_detect.py).

Signal model (see docs/flights.md): the continuity circuit is a switch, ``s(t)`` in
{0: open, 1: contact}, seen through a first-order RC front end with ``q = exp(-1/tau)``
(tau in samples) and sampled instantaneously: ``u[k] = s`` filtered, in units where the
open level is 0 and the contact level 1.  Deconvolving one step,
``z[k] = (u[k] - q u[k-1]) / (1 - q)``, gives the exponentially weighted fraction of
the interval ``(k-1, k]`` spent in contact, which locates an edge inside the interval.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

# edge kinds in the edge list
LANDING = 1  # open -> contact
TAKEOFF = -1  # contact -> open


@njit(cache=True)
def block_levels_serial(x, block, lo0, hi0, min_count):
    """Robust two-level estimate per block (two passes of banded means per block).

    Parameters
    ----------
    x : (n,) float array, volts.
    block : int, samples per block.
    lo0, hi0 : float, starting low and high levels (volts), e.g. the global estimate.
    min_count : int, samples a level needs in a block to be trusted there.

    Returns
    -------
    lo, hi : (n_blocks,) levels in volts, NaN where a level has too few samples.
    frac_hi : (n_blocks,) fraction of samples above the mid level.
    sd : (n_blocks,) pooled standard deviation of the samples near either level (volts),
        NaN when neither level is trusted.

    Only samples within a quarter of the level gap from a level count for it, so RC
    transitions and partial one-sample dips hardly bias the levels; levels are carried
    from block to block, so slow drift is followed.
    """
    n = x.shape[0]
    nb = (n + block - 1) // block
    lo = np.full(nb, np.nan)
    hi = np.full(nb, np.nan)
    frac_hi = np.zeros(nb)
    sd = np.full(nb, np.nan)
    clo = lo0
    chi = hi0
    for b in range(nb):
        a = b * block
        e = min(n, a + block)
        clo, chi, slo, qlo, nlo, shi, qhi, nhi, nabove = _two_pass_levels(
            x, a, e, clo, chi, min_count
        )
        frac_hi[b] = nabove / (e - a)
        if nlo >= min_count:
            lo[b] = clo
        if nhi >= min_count:
            hi[b] = chi
        sd[b] = _pooled_sd(slo, qlo, nlo, shi, qhi, nhi, min_count)
    return lo, hi, frac_hi, sd


@njit(cache=True, nogil=True)
def _two_pass_levels(x, a, e, clo, chi, min_count):
    """One block ``x[a:e]`` of :func:`block_levels_serial`: two passes of banded means
    from the carried levels ``(clo, chi)``.

    Returns the new levels and the second pass's sums: ``(clo, chi, slo, qlo, nlo, shi,
    qhi, nhi, nabove)`` (sum, sum of squares and count of the samples in the low and the
    high band; samples above the mid level).
    """
    slo = shi = qlo = qhi = 0.0
    nlo = nhi = nabove = 0
    for _ in range(2):
        blo, mid, bhi = _band_edges(clo, chi)
        slo = shi = qlo = qhi = 0.0
        nlo = nhi = nabove = 0
        for i in range(a, e):
            v = x[i]
            if v > mid:
                nabove += 1
            if v < blo:
                slo += v
                qlo += v * v
                nlo += 1
            elif v > bhi:
                shi += v
                qhi += v * v
                nhi += 1
        if nlo >= min_count:
            clo = slo / nlo
        if nhi >= min_count:
            chi = shi / nhi
    return clo, chi, slo, qlo, nlo, shi, qhi, nhi, nabove


@njit(cache=True, nogil=True)
def _pooled_sd(slo, qlo, nlo, shi, qhi, nhi, min_count):
    """Pooled standard deviation (volts) of the samples near either level, from each
    level's sum ``s``, sum of squares ``q`` and count ``n``; a level with fewer than
    ``min_count`` samples is left out, NaN when both are."""
    ss = 0.0
    cnt = 0
    if nlo >= min_count:
        ss += qlo - slo * slo / nlo
        cnt += nlo - 1
    if nhi >= min_count:
        ss += qhi - shi * shi / nhi
        cnt += nhi - 1
    return math.sqrt(max(ss, 0.0) / cnt) if cnt > 0 else np.nan


@njit(cache=True)
def _segment(k, block, centers_open, centers_inv):
    """Linear pieces of the levels around sample k, for incremental evaluation.

    Returns ``(k_start, k_end, o0, o_slope, i0, i_slope)``: for ``k_start <= j < k_end``
    the open level is ``o0 + o_slope (j - k_start)`` and the inverse gap
    ``i0 + i_slope (j - k_start)`` (per-sample cost: two multiply-adds, no division).
    """
    nb = centers_open.shape[0]
    half = block // 2
    if nb == 1 or k < half:
        return 0, half if nb > 1 else 1 << 62, centers_open[0], 0.0, centers_inv[0], 0.0
    j = (k - half) // block
    if j >= nb - 1:
        return (nb - 1) * block + half, 1 << 62, centers_open[nb - 1], 0.0, centers_inv[nb - 1], 0.0
    ks = j * block + half
    so = (centers_open[j + 1] - centers_open[j]) / block
    si = (centers_inv[j + 1] - centers_inv[j]) / block
    return ks, ks + block, centers_open[j], so, centers_inv[j], si


@njit(cache=True)
def rc_ratios_serial(x, block, open_b, inv_b, max_out):
    """Decay ratios right after clean edges, to estimate the RC constant q = exp(-1/tau).

    After a takeoff inside ``(k-1, k]`` the filtered signal only decays, so
    ``u[k+1] = q u[k]`` exactly (and ``1-u`` likewise after a landing).  A ratio is
    taken only at clean, held edges: two samples at the old level (within 0.1 of the
    gap), the first sample after the edge between 0.3 and 0.95 of the way (0.05-0.7
    for landings), the next moving on, and the one after that within 0.1 of the new
    level (so a chatter impact or a one-sample contact does not spoil the ratio): the
    ``strict`` ratios. Those whose third sample is not that close but still decays at
    the same ratio (:func:`_settle_kind`: a front end slower than the sampling) are
    returned apart, as ``slow`` ratios.
    Returns ``(strict, slow)``, up to ``max_out`` of each.
    """
    n = x.shape[0]
    strict = np.empty(max_out)
    slow = np.empty(max_out)
    m = 0
    ms = 0
    if n < 5:
        return strict[:0], slow[:0]
    u = np.empty(5)  # u[k-1], u[k], u[k+1], u[k+2], u[k+3] of the window
    ks, ke, o0, so, i0, si = _segment(0, block, open_b, inv_b)
    for k in range(n):
        if k >= ke:
            ks, ke, o0, so, i0, si = _segment(k, block, open_b, inv_b)
        d = k - ks
        for j in range(4):
            u[j] = u[j + 1]
        u[4] = (x[k] - (o0 + so * d)) * (i0 + si * d)
        if k < 4:
            continue
        kind, r = _rc_window(u[0], u[1], u[2], u[3], u[4])
        m, ms = _keep_ratio(strict, slow, m, ms, kind, r)
    return strict[:m], slow[:ms]


@njit(cache=True, inline="always")
def _settle_kind(a2, a3, a4):
    """How the distances ``a2 > a3``, ``a4`` to the new level (fractions of the gap) of
    the three samples after an edge settle: 2 when ``a4`` is within 0.1 of the level;
    1 when it is not but still falls, at a ratio ``a3 / a2`` below 0.9, to within 0.1 (one RC
    decay on a front end slower than the sampling, tau over about 1.5 samples, whose
    third sample is never that close); 0 otherwise (a chatter impact or one-sample
    contact turns the signal back). Kind 1 is only a fallback: an offset of the levels
    (an uncorrected hum) also "decays at one ratio", near 1."""
    if a4 < 0.1:
        return 2
    # a ratio near 1 is no decay: a level held beside noise (a 6 %-noise drop test read
    # its noise as a "tau of 10 samples", q 0.9, and lost every bounce)
    if a3 < 0.9 * a2 and a4 < a3 and abs(a4 * a2 - a3 * a3) < 0.1 * a2 * a3:
        return 1
    return 0


@njit(cache=True, inline="always")
def _rc_window(u0, u1, u2, u3, u4):
    """``(kind, ratio)`` of the window ``u[k-1..k+3]`` of :func:`rc_ratios_serial`:
    kind 2 (strict) or 1 (slow front end) with the decay ratio after a clean, held
    edge, 0 (and 0.0) for any other window."""
    # takeoff after a held contact, then two samples that settle towards open
    if u0 > 0.9 and u1 > 0.9 and 0.3 < u2 < 0.95 and u3 < u2:
        kind = _settle_kind(u2, u3, u4)
        if kind:
            return kind, u3 / u2
    # landing after a held opening, then two samples that settle towards contact
    if u0 < 0.1 and u1 < 0.1 and 0.05 < u2 < 0.7 and u3 > u2:
        kind = _settle_kind(1.0 - u2, 1.0 - u3, 1.0 - u4)
        if kind:
            return kind, (1.0 - u3) / (1.0 - u2)
    return 0, 0.0


@njit(cache=True, inline="always")
def _keep_ratio(strict, slow, m, ms, kind, r):
    """Append ``r`` to ``strict`` (kind 2) or ``slow`` (kind 1) while each has room;
    returns their new fill counts ``(m, ms)``."""
    if kind == 2 and m < strict.shape[0]:
        strict[m] = r
        m += 1
    elif kind == 1 and ms < slow.shape[0]:
        slow[ms] = r
        ms += 1
    return m, ms


Q_MIN = 1e-4  # below this the RC leaves no trace in the next sample: box model


@njit(cache=True)
def _invert(a, k, q, tau, a_lim):
    """Edge time from ``a = exp(-(k - t)/tau)`` in [q, 1]; when ``a`` is below what the
    noise lets us resolve (``a_lim``), the edge is somewhere in ``(k-1, k + tau ln a_lim)``
    and is put in the middle of that range."""
    if a >= a_lim:
        return k + tau * math.log(min(a, 1.0))
    return 0.5 * (k - 1.0 + k + tau * math.log(a_lim))


@njit(cache=True)
def _rise_time(z, k, q, tau, sdz):
    """Time of an open->contact edge inside (k-1, k] whose contact lasts past k."""
    z = min(max(z, 0.0), 1.0)
    if q < Q_MIN:  # front end far faster than the sampling: box model, linear in z
        return k - z
    a_lim = q + 3.0 * sdz * (1.0 - q)
    return _invert(1.0 - z * (1.0 - q), k, q, tau, a_lim)


@njit(cache=True)
def _fall_time(z, k, q, tau, sdz):
    """Time of a contact->open edge inside (k-1, k] when contact held from k-1."""
    z = min(max(z, 0.0), 1.0)
    if q < Q_MIN:
        return k - 1.0 + z
    a_lim = q + 3.0 * sdz * (1.0 - q)
    return _invert(q + z * (1.0 - q), k, q, tau, a_lim)


@njit(cache=True)
def _pulse_in_interval(w, k, q, tau, d_prior):
    """Start and end of a pulse lying wholly inside (k-1, k] with weighted area w.

    One sample gives one number, ``w (1-q) = exp(-(k-t_end)/tau) (1 - exp(-d/tau))``, so
    the pulse is placed with a prior duration ``d_prior`` (samples; <= 0: none) and, with
    no prior, at the middle of the positions the number allows.
    """
    w = min(max(w, 1e-9), 1.0)
    if q < Q_MIN:
        d = w
        c = k - 0.5
        return c - 0.5 * d, c + 0.5 * d
    a = w * (1.0 - q)
    if d_prior > 0.0:
        den = 1.0 - math.exp(-d_prior / tau)
        r = a / den
        if r <= 1.0:
            t_end = k + tau * math.log(r)
            d = d_prior
            if t_end - d >= k - 1.0:
                return t_end - d, t_end
    # no usable prior: t_end between the pulse starting at k-1 and ending at k
    t_end_min = k + tau * math.log(min(a + q, 1.0))
    t_end = 0.5 * (t_end_min + k)
    r = 1.0 - a * math.exp((k - t_end) / tau)
    d = -tau * math.log(max(r, 1e-300))
    t_start = max(t_end - d, k - 1.0)
    return t_start, t_end


HELD_TOL = 0.03  # least change of z (share of the gap) between two intervals of a held level
HELD_RUN = 4  # intervals at one level that make it held (chatter rarely gives three alike)
HELD_NONE, HELD_ON, HELD_EDGE = 0, 1, 2  # readings of :func:`_held_reading`


@njit(cache=True, nogil=True)
def _z_raw(x, j, block, open_b, inv_b, q):
    """Contact fraction of interval ``j >= 1`` from the raw samples (glitches kept)."""
    return (u_at(x, j, block, open_b, inv_b) - q * u_at(x, j - 1, block, open_b, inv_b)) / (1.0 - q)


@njit(cache=True, nogil=True)
def _level_run(x, j0, step, level, tol, block, open_b, inv_b, q):
    """Consecutive intervals from ``j0`` on, in direction ``step`` (+-1), at most
    ``HELD_RUN``, whose fraction is ``level`` within ``tol``."""
    n = x.shape[0]
    run = 0
    j = j0
    while run < HELD_RUN and 1 <= j < n:
        if abs(_z_raw(x, j, block, open_b, inv_b, q) - level) > tol:
            break
        run += 1
        j += step
    return run


@njit(cache=True, nogil=True)
def _held_reading(x, k, state, block, open_b, inv_b, q, thr, sdz):
    """Reading of interval ``k``, whose contact fraction is partial, where the channel
    holds a level between open and contact (a contact that half-conducts).

    A held level: :data:`HELD_RUN` consecutive intervals at one partial fraction (within
    ``max(6 sdz, HELD_TOL)``); real edges do not make that (a takeoff inside an interval
    leaves the next one open, sub-sample chatter gives a few unequal fractions).  Read as
    one contact: it starts where the level starts, ends where it ends, and the intervals
    where the level meets open or contact are shares of the level, not of the gap.
    Without this each held sample was read as a contact of its own.  Most edges have
    no partial neighbour (full contact on one side, open on the other) and leave after
    reading four samples; the runs are read only beside a partial neighbour.

    Returns ``(reading, t)``: :data:`HELD_NONE` (no held level here: the usual reading),
    :data:`HELD_ON` (in contact: the contact goes on, no edge) or :data:`HELD_EDGE` (one
    edge at ``t``, samples: a landing from ``state`` 0, a takeoff from 1).  Fractions
    are read from the raw samples, so that every pass, serial or in pieces, reads alike.
    """
    n = x.shape[0]
    if k < 2 or k + 1 >= n:
        return HELD_NONE, 0.0
    u_before = u_at(x, k - 1, block, open_b, inv_b)
    u_here = u_at(x, k, block, open_b, inv_b)
    u_after = u_at(x, k + 1, block, open_b, inv_b)
    z = (u_here - q * u_before) / (1.0 - q)
    z_next = (u_after - q * u_here) / (1.0 - q)
    ahead = z_next >= thr and z_next < 1.0 - thr
    if not ahead:
        if state == 0:
            return HELD_NONE, 0.0
        # in contact a held level needs a partial neighbour: most edges have none
        z_prev = (u_before - q * u_at(x, k - 2, block, open_b, inv_b)) / (1.0 - q)
        if not (z_prev >= thr and z_prev < 1.0 - thr):
            return HELD_NONE, 0.0
    tol = max(6.0 * sdz, HELD_TOL)
    if ahead:
        ahead = _level_run(x, k + 1, 1, z_next, tol, block, open_b, inv_b, q) >= HELD_RUN - 1
    if state == 0:
        if ahead and z <= z_next + tol:  # a held level starts in this interval
            return HELD_EDGE, k - min(z / z_next, 1.0)
        return HELD_NONE, 0.0
    own = 1 + _level_run(x, k - 1, -1, z, tol, block, open_b, inv_b, q)
    own += _level_run(x, k + 1, 1, z, tol, block, open_b, inv_b, q)
    if own >= HELD_RUN or (ahead and z >= z_next - tol):
        if z_next < thr:
            return HELD_EDGE, float(k)  # the level ends with the interval
        return HELD_ON, 0.0  # it goes on, or meets full contact
    z_prev = _z_raw(x, k - 1, block, open_b, inv_b, q)
    if (
        z_prev >= thr
        and z_prev < 1.0 - thr
        and _level_run(x, k - 1, -1, z_prev, tol, block, open_b, inv_b, q) >= HELD_RUN - 1
    ):
        if z_next < thr:  # the level ends inside this interval
            return HELD_EDGE, k - 1.0 + min(z / z_prev, 1.0)
        return HELD_ON, 0.0
    return HELD_NONE, 0.0


@njit(cache=True)
def detect_edges_serial(x, block, open_b, inv_b, sdz_b, q, thr_min, thr_max, d_prior, glitch_k):
    """Single pass: glitch rejection, RC deconvolution, edge times with sub-sample precision.

    Parameters
    ----------
    x : (n,) samples, volts.
    block, open_b, inv_b : levels: open level (volts) and 1 / (contact - open) (1/V) at
        block centres (negative for a low contact level).
    sdz_b : (n_blocks,) noise of z (in units of the gap) per block.
    q : float, RC decay per sample (0 for none).
    thr_min, thr_max : bounds of the detection threshold on z (fraction of the gap);
        the threshold is ``clip(6 sdz, thr_min, thr_max)``.
    d_prior : float, prior contact duration in samples for pulses inside one interval
        (<= 0: none).
    glitch_k : float, noise multiples that make a sample a glitch (see below).

    Returns
    -------
    t : (m,) edge times in samples (float), sorted.
    kind : (m,) int8, LANDING (+1) or TAKEOFF (-1); kinds alternate.
    n_glitch : (n_blocks,) int64, glitches removed per block.
    n_contact : (n_blocks,) int64, samples in contact per block.
    first_state : int, state (1 contact) at sample 0.
    glitch_at : (g,) int64, indices of the first 4096 glitches removed.

    Glitch rule: a sample ``u[k]`` is replaced by the mean of its neighbours when
    (a) it lies beyond the levels by more than 0.3 of the gap plus ``glitch_k`` noise,
    which an RC-smoothed switch cannot do, or (b) it makes the deconvolved fraction of
    the next interval leave [0, 1] by more than ``glitch_k`` noise while its own
    interval deviates the other way: a real contact or opening, however short, decays
    through the RC front end into the next sample (``u[k+1] - s = q (u[k] - s)``), a
    one-sample electrical spike does not.  Limit: rule (b) needs a measurable RC
    (``q >= 0.02``) and a spike larger than about ``glitch_k sigma_z (1-q)/q`` of the gap;
    with a front end faster than the sampling a one-sample spike inside the levels
    cannot be told from a one-sample contact and is kept.
    """
    n = x.shape[0]
    nb = open_b.shape[0]
    cap = 1024
    t_out = np.empty(cap)
    k_out = np.empty(cap, dtype=np.int8)
    m = 0
    n_glitch = np.zeros(nb, dtype=np.int64)
    n_contact = np.zeros(nb, dtype=np.int64)
    g_cap = 4096
    g_out = np.empty(g_cap, dtype=np.int64)
    n_g = 0
    if n < 3:
        return t_out[:0], k_out[:0], n_glitch, n_contact, 0, g_out[:0]
    tau = -1.0 / math.log(q) if q > 1e-12 else 0.0
    inv1q = 1.0 / (1.0 - q)
    # u values: previous (already cleaned), current, next
    ks, ke, o0, so, i0, si = _segment(0, block, open_b, inv_b)
    u_prev = (x[0] - o0) * i0
    u_cur = (x[1] - (o0 + so)) * (i0 + si)
    state = 1 if u_prev > 0.5 else 0
    first_state = state
    # the z of interval k needs u[k] cleaned, which needs u[k+1]: keep a one-sample lag
    for k in range(1, n):
        b = k // block
        sdz = sdz_b[b]
        thr = min(max(6.0 * sdz, thr_min), thr_max)
        # whether an edge's new state carries on into the next interval only needs z to
        # stand out of the noise (and of a 15 % error of q): after a pulse that ended
        # inside the interval the deconvolved next z is exactly 0, while a contact that
        # ends early in the next interval leaves only a small weighted fraction there
        thr_c = min(max(6.0 * sdz, 0.15 * q), thr)
        sdu = sdz * (1.0 - q)
        if k + 1 < n:
            if k + 1 >= ke:
                ks, ke, o0, so, i0, si = _segment(k + 1, block, open_b, inv_b)
            d = k + 1 - ks
            u_nxt = (x[k + 1] - (o0 + so * d)) * (i0 + si * d)
            # glitch test on u_cur: (a) beyond the levels, (b) z out of [0, 1]
            bad = u_cur > 1.3 + glitch_k * sdu or u_cur < -0.3 - glitch_k * sdu
            if not bad and q >= 0.02:  # (b) needs a visible RC tail
                mz = glitch_k * sdz
                z_here = (u_cur - q * u_prev) * inv1q
                z_after = (u_nxt - q * u_cur) * inv1q
                # a spike at k lifts z[k] and drives z[k+1] below 0 (or the mirror image);
                # an RC-smoothed switch keeps every z in [0, 1] up to noise
                if (z_after < -mz and z_here > mz) or (z_after > 1.0 + mz and z_here < 1.0 - mz):
                    bad = True
            if bad:
                u_cur = 0.5 * (u_prev + u_nxt)
                n_glitch[b] += 1
                if n_g < g_cap:
                    g_out[n_g] = k
                    n_g += 1
        else:
            u_nxt = u_cur
        z = (u_cur - q * u_prev) * inv1q
        # z of the following interval (u_nxt not yet cleaned): look-ahead for partials
        z_next = (u_nxt - q * u_cur) * inv1q
        have_next = k + 1 < n
        if m + 2 >= cap:
            cap *= 2
            t2 = np.empty(cap)
            k2 = np.empty(cap, dtype=np.int8)
            t2[:m] = t_out[:m]
            k2[:m] = k_out[:m]
            t_out = t2
            k_out = k2
        held, t_held = HELD_NONE, 0.0
        if thr <= z < 1.0 - thr:
            held, t_held = _held_reading(x, k, state, block, open_b, inv_b, q, thr, sdz)
        if held == HELD_EDGE:
            t_out[m] = t_held
            k_out[m] = LANDING if state == 0 else TAKEOFF
            m += 1
            state = 1 - state
        elif state == 0:
            if z >= thr:
                if z >= 1.0 - thr or (have_next and z_next >= thr_c):
                    t_out[m] = _rise_time(z, k, q, tau, sdz)
                    k_out[m] = LANDING
                    m += 1
                    state = 1
                else:
                    ta, tb = _pulse_in_interval(z, k, q, tau, d_prior)
                    t_out[m] = ta
                    k_out[m] = LANDING
                    t_out[m + 1] = tb
                    k_out[m + 1] = TAKEOFF
                    m += 2
        elif held == HELD_NONE:
            w = 1.0 - z
            if w >= thr:
                if w >= 1.0 - thr or (have_next and 1.0 - z_next >= thr_c):
                    t_out[m] = _fall_time(z, k, q, tau, sdz)
                    k_out[m] = TAKEOFF
                    m += 1
                    state = 0
                else:
                    # brief opening inside the interval: a sub-sample flight
                    ta, tb = _pulse_in_interval(w, k, q, tau, 0.0)
                    t_out[m] = ta
                    k_out[m] = TAKEOFF
                    t_out[m + 1] = tb
                    k_out[m + 1] = LANDING
                    m += 2
        if state == 1:
            n_contact[b] += 1
        u_prev = u_cur
        u_cur = u_nxt
    return t_out[:m], k_out[:m], n_glitch, n_contact, first_state, g_out[:n_g]


# ---------------------------------------------------------------------------------------
# Fast kernels.  Each gives exactly (bit for bit) what its ``*_serial`` reference above
# gives; they are only arranged differently: work split into independent pieces that
# run on several cores, per-block constants hoisted out of the per-sample loop.
# ---------------------------------------------------------------------------------------


@njit(cache=True, nogil=True)
def u_at(x, k, block, open_b, inv_b):
    """Normalised sample ``u[k]`` (0 open, 1 contact), exactly as the serial kernels
    compute it incrementally (same segment, same operations)."""
    ks, ke, o0, so, i0, si = _segment(k, block, open_b, inv_b)
    d = k - ks
    return (x[k] - (o0 + so * d)) * (i0 + si * d)


@njit(cache=True, nogil=True)
def edge_range(
    x, k0, k1, state, u_prev, block, open_b, inv_b, sdz_b, q, thr_min, thr_max, d_prior, glitch_k
):
    """Iterations ``k0 <= k < k1`` of :func:`detect_edges_serial`, from a given state.

    The serial pass carries only ``state`` (1 contact) and ``u_prev`` (the cleaned
    ``u[k0-1]``) from one iteration to the next; everything else is a function of ``k``
    and the samples.  So the pass can be cut anywhere: started with the state the serial
    pass has before iteration ``k0``, this gives exactly the serial pass's edges of those
    iterations.  ``k0 >= 1``; ``x`` is the whole (n,) recording (the last iteration,
    ``k = n-1``, has no look-ahead, as in the serial pass).

    Speed: a tight loop runs over the quiet samples (no glitch, no threshold crossed:
    the same tests, the same floating-point expressions as the serial pass) and hands
    every other iteration to the full serial iteration body (:func:`_full_iteration`).

    Returns
    -------
    t : (m,) float64 edge times, samples;  kind : (m,) int8 (LANDING / TAKEOFF).
    glitch_at : (g,) int64, the first 4096 glitches of the range (sample indices).
    n_glitch, n_contact : (b1 - b0 + 1,) int64 counts for the blocks
        ``b0 = k0 // block`` .. ``b1 = (k1 - 1) // block`` of the range.
    state, u_prev : the carried state after iteration ``k1 - 1``.
    pulse_at, pulse_k, pulse_z : (p,) int64, int64, float64: for every contact found
        wholly inside one interval (open state), the index of its first edge in ``t``,
        the interval ``k`` and its weighted area ``z``.  Only the placement of such
        contacts depends on ``d_prior`` (:func:`place_pulses` redoes it).
    """
    n = x.shape[0]
    b0 = k0 // block
    b1 = max(k1 - 1, k0) // block
    n_glitch = np.zeros(b1 - b0 + 1, dtype=np.int64)
    n_contact = np.zeros(b1 - b0 + 1, dtype=np.int64)
    cap = 1024
    t_out = np.empty(cap)
    k_out = np.empty(cap, dtype=np.int8)
    m = 0
    g_cap = 4096
    g_out = np.empty(g_cap, dtype=np.int64)
    n_g = 0
    p_cap = 256
    p_at = np.empty(p_cap, dtype=np.int64)
    p_k = np.empty(p_cap, dtype=np.int64)
    p_z = np.empty(p_cap)
    n_p = 0
    if k1 <= k0:
        return (
            t_out[:0], k_out[:0], g_out[:0], n_glitch, n_contact, state, u_prev,
            p_at[:0], p_k[:0], p_z[:0],
        )  # fmt: skip
    inv1q = 1.0 / (1.0 - q)
    rule_b = q >= 0.02  # glitch rule (b) needs a visible RC tail
    ks, ke, o0, so, i0, si = _segment(k0, block, open_b, inv_b)
    d = k0 - ks
    u_cur = (x[k0] - (o0 + so * d)) * (i0 + si * d)
    k = k0
    while k < k1:
        b = k // block
        k_end = min(k1, (b + 1) * block)
        k_quiet = min(k_end, n - 1)  # the last sample (no look-ahead) takes the full path
        # per-block constants: the same expressions the serial pass evaluates per sample
        sdz = sdz_b[b]
        thr = min(max(6.0 * sdz, thr_min), thr_max)
        sdu = sdz * (1.0 - q)
        g_hi = 1.3 + glitch_k * sdu
        g_lo = -0.3 - glitch_k * sdu
        mz = glitch_k * sdz
        ng = 0
        nc = 0
        while k < k_end:
            u_nxt = u_cur
            # quiet samples: nothing but the state's contact count changes
            while k < k_quiet:
                if k + 1 >= ke:
                    ks, ke, o0, so, i0, si = _segment(k + 1, block, open_b, inv_b)
                d = k + 1 - ks
                u_nxt = (x[k + 1] - (o0 + so * d)) * (i0 + si * d)
                if u_cur > g_hi or u_cur < g_lo:
                    break
                z = (u_cur - q * u_prev) * inv1q
                if rule_b:
                    z_after = (u_nxt - q * u_cur) * inv1q
                    if (z_after < -mz and z > mz) or (z_after > 1.0 + mz and z < 1.0 - mz):
                        break
                if state == 0:
                    if z >= thr:
                        break
                elif 1.0 - z >= thr:
                    break
                nc += state
                u_prev = u_cur
                u_cur = u_nxt
                k += 1
            if k >= k_end:
                break
            # iteration k in full (u_nxt is u[k+1], or u_cur at the last sample)
            state, u_clean, glitch, n_new, ta, ka, tb, kb, z = _full_iteration(
                x, block, open_b, inv_b, k, k + 1 < n, state, u_prev, u_cur, u_nxt, q, sdz,
                thr_min, thr_max, d_prior, glitch_k,
            )  # fmt: skip
            if glitch:
                ng += 1
                if n_g < g_cap:
                    g_out[n_g] = k
                    n_g += 1
            if n_new > 0:
                if m + 2 >= cap:
                    t_out, k_out, cap = _grow(t_out, k_out, m, cap)
                t_out[m] = ta
                k_out[m] = ka
                if n_new == 2:
                    t_out[m + 1] = tb
                    k_out[m + 1] = kb
                    if ka == LANDING:  # a contact inside the interval: keep for place_pulses
                        if n_p == p_cap:
                            p_at, p_k, p_z, p_cap = _grow_pulses(p_at, p_k, p_z, n_p, p_cap)
                        p_at[n_p] = m
                        p_k[n_p] = k
                        p_z[n_p] = z
                        n_p += 1
                m += n_new
            nc += state
            u_prev = u_clean
            u_cur = u_nxt
            k += 1
        n_glitch[b - b0] += ng
        n_contact[b - b0] += nc
    return (
        t_out[:m], k_out[:m], g_out[:n_g], n_glitch, n_contact, state, u_prev,
        p_at[:n_p], p_k[:n_p], p_z[:n_p],
    )  # fmt: skip


@njit(cache=True, nogil=True)
def _full_iteration(
    x, block, open_b, inv_b, k, have_next, state, u_prev, u_cur, u_nxt, q, sdz, thr_min,
    thr_max, d_prior, glitch_k,
):  # fmt: skip
    """One iteration of :func:`detect_edges_serial` (its loop body, same expressions).

    ``u_nxt`` is ``u[k+1]`` (``u_cur`` when ``have_next`` is false); the samples and
    levels are read again only where ``z`` is partial (:func:`_held_reading`).  Returns
    ``(state, u_clean, glitch, n_new, t_a, kind_a, t_b, kind_b, z)``: the new state, the
    cleaned ``u[k]`` (the next ``u_prev``), whether ``u[k]`` was a glitch, the 0, 1 or 2
    edges found in the interval ``(k-1, k]``, and its contact fraction ``z``.
    """
    tau = -1.0 / math.log(q) if q > 1e-12 else 0.0
    inv1q = 1.0 / (1.0 - q)
    thr = min(max(6.0 * sdz, thr_min), thr_max)
    thr_c = min(max(6.0 * sdz, 0.15 * q), thr)
    sdu = sdz * (1.0 - q)
    glitch = False
    if have_next:
        bad = u_cur > 1.3 + glitch_k * sdu or u_cur < -0.3 - glitch_k * sdu
        if not bad and q >= 0.02:
            mz = glitch_k * sdz
            z_here = (u_cur - q * u_prev) * inv1q
            z_after = (u_nxt - q * u_cur) * inv1q
            if (z_after < -mz and z_here > mz) or (z_after > 1.0 + mz and z_here < 1.0 - mz):
                bad = True
        if bad:
            u_cur = 0.5 * (u_prev + u_nxt)
            glitch = True
    z = (u_cur - q * u_prev) * inv1q
    z_next = (u_nxt - q * u_cur) * inv1q
    n_new = 0
    ta = 0.0
    tb = 0.0
    ka = LANDING
    kb = TAKEOFF
    held, t_held = HELD_NONE, 0.0
    if thr <= z < 1.0 - thr:
        held, t_held = _held_reading(x, k, state, block, open_b, inv_b, q, thr, sdz)
    if held == HELD_EDGE:
        ta = t_held
        ka = LANDING if state == 0 else TAKEOFF
        n_new = 1
        state = 1 - state
    elif state == 0:
        if z >= thr:
            if z >= 1.0 - thr or (have_next and z_next >= thr_c):
                ta = _rise_time(z, k, q, tau, sdz)
                n_new = 1
                state = 1
            else:
                ta, tb = _pulse_in_interval(z, k, q, tau, d_prior)
                n_new = 2
    elif held == HELD_NONE:
        w = 1.0 - z
        if w >= thr:
            ka = TAKEOFF
            kb = LANDING
            if w >= 1.0 - thr or (have_next and 1.0 - z_next >= thr_c):
                ta = _fall_time(z, k, q, tau, sdz)
                n_new = 1
                state = 0
            else:
                # brief opening inside the interval: a sub-sample flight
                ta, tb = _pulse_in_interval(w, k, q, tau, 0.0)
                n_new = 2
    return state, u_cur, glitch, n_new, ta, ka, tb, kb, z


@njit(cache=True, nogil=True)
def _grow_pulses(p_at, p_k, p_z, n_p, cap):
    """Double the capacity of the pulse records (first ``n_p`` kept)."""
    cap *= 2
    a2 = np.empty(cap, dtype=np.int64)
    k2 = np.empty(cap, dtype=np.int64)
    z2 = np.empty(cap)
    a2[:n_p] = p_at[:n_p]
    k2[:n_p] = p_k[:n_p]
    z2[:n_p] = p_z[:n_p]
    return a2, k2, z2, cap


@njit(cache=True, nogil=True)
def place_pulses(t, pulse_at, pulse_k, pulse_z, q, d_prior):
    """Place again, with the prior duration ``d_prior`` (samples), the contacts lying
    wholly inside one interval (records of :func:`edge_range`): writes both edges of
    each into ``t`` (in place) exactly as :func:`detect_edges_serial` run with
    ``d_prior`` places them (the state machine itself does not depend on ``d_prior``)."""
    tau = -1.0 / math.log(q) if q > 1e-12 else 0.0
    for j in range(pulse_at.shape[0]):
        i = pulse_at[j]
        ta, tb = _pulse_in_interval(pulse_z[j], pulse_k[j], q, tau, d_prior)
        t[i] = ta
        t[i + 1] = tb


@njit(cache=True, nogil=True)
def _grow(t_out, k_out, m, cap):
    """Double the capacity of the edge buffers (first ``m`` entries kept)."""
    cap *= 2
    t2 = np.empty(cap)
    k2 = np.empty(cap, dtype=np.int8)
    t2[:m] = t_out[:m]
    k2[:m] = k_out[:m]
    return t2, k2, cap


# columns of the per-block records of the fast block_levels: per banded-means iteration
# (first, second), the count and mean of each band and the brackets of the band edges
_NLO, _NHI, _MLO, _MHI, _LB, _LA, _HB, _HA = 0, 1, 2, 3, 4, 5, 6, 7
_IT = 8  # columns per iteration; after the two iterations:
_MB, _MA, _FRAC, _SD = 16, 17, 18, 19  # brackets of the second mid level, frac_hi, sd
_MIN, _MAX = 20, 21  # the block's extremes (NaN when it holds a NaN)
_NCOL = 22


@njit(cache=True, nogil=True)
def _banded_pass(x, a, e, blo, mid, bhi):
    """One banded-means iteration of :func:`block_levels_serial` over ``x[a:e]``.

    Same membership tests (``v < blo`` low band, else ``v > bhi`` high band), same
    arithmetic (squares in the input precision), same summation order as the serial
    kernel, for ``blo <= mid <= bhi``.  Also returns the brackets of the band edges and
    of the mid level: the largest sample below ``blo`` and the smallest at or above it;
    the largest at or below ``mid`` / ``bhi`` and the smallest above it.  Any other band
    edges and mid level inside the same brackets select the same samples, hence give the
    same sums (the samples fall in four ranges split by ``blo``, ``mid``, ``bhi``; the
    brackets are the extremes of those ranges).

    Returns ``(slo, qlo, nlo, shi, qhi, nhi, nabove, lo_below, lo_above, mid_below,
    mid_above, hi_below, hi_above, v_min, v_max, has_nan)``: the last three are the
    extremes of ``x[a:e]`` and whether it holds a NaN (for the stuck-rail check).
    """
    slo = 0.0
    shi = 0.0
    qlo = 0.0
    qhi = 0.0
    nlo = 0
    nhi = 0
    n_r2 = 0  # mid < v <= bhi
    max0 = -np.inf  # v < blo
    min1 = np.inf  # blo <= v <= mid
    max1 = -np.inf
    min2 = np.inf  # mid < v <= bhi
    max2 = -np.inf
    min3 = np.inf  # v > bhi
    min0 = np.inf
    max3 = -np.inf
    has_nan = False
    for i in range(a, e):
        v = x[i]
        if v < blo:
            slo += v
            qlo += v * v
            nlo += 1
            max0 = max(max0, v)
            min0 = min(min0, v)
        elif v > bhi:
            shi += v
            qhi += v * v
            nhi += 1
            min3 = min(min3, v)
            max3 = max(max3, v)
        elif v > mid:
            n_r2 += 1
            min2 = min(min2, v)
            max2 = max(max2, v)
        elif v == v:
            min1 = min(min1, v)
            max1 = max(max1, v)
        else:  # NaN: in no band, as in the serial kernel
            has_nan = True
    lo_above = min(min1, min(min2, min3))
    mid_below = max(max0, max1)
    mid_above = min(min2, min3)
    hi_below = max(mid_below, max2)
    v_min = min(min0, lo_above)
    v_max = max(hi_below, max3)
    return (
        slo, qlo, nlo, shi, qhi, nhi, nhi + n_r2,
        max0, lo_above, mid_below, mid_above, hi_below, min3, v_min, v_max, has_nan,
    )  # fmt: skip


@njit(cache=True, nogil=True)
def _band_edges(clo, chi):
    """Band edges and mid level of :func:`block_levels_serial` (same expressions)."""
    gap = chi - clo
    return clo + 0.25 * gap, 0.5 * (clo + chi), chi - 0.25 * gap


@njit(cache=True, nogil=True)
def _level_block(x, a, e, clo, chi, min_count, rec, row):
    """The per-block body of :func:`block_levels_serial` from the carried levels
    ``(clo, chi)``, with the same result; writes the record ``rec[row]`` (columns above)
    and returns the levels carried on.

    The second banded-means iteration selects the same samples as the first whenever
    its band edges and mid level stay in the first one's brackets (the usual case: the
    levels move by a fraction of the noise); then its sums are the first one's, and the
    samples are read once.
    """
    clo0, chi0 = clo, chi
    blo, mid, bhi = _band_edges(clo, chi)
    if not (blo <= mid <= bhi):  # not two ordered levels (NaN, or crossed): plain serial
        return _level_block_plain(x, a, e, clo0, chi0, min_count, rec, row)
    r = _banded_pass(x, a, e, blo, mid, bhi)
    _store(rec, row, 0, r)
    rec[row, _MIN] = np.nan if r[15] else r[13]
    rec[row, _MAX] = np.nan if r[15] else r[14]
    if r[2] >= min_count:
        clo = r[0] / r[2]
    if r[5] >= min_count:
        chi = r[3] / r[5]
    blo, mid, bhi = _band_edges(clo, chi)
    same = r[7] < blo <= r[8] and r[9] <= mid < r[10] and r[11] <= bhi < r[12]
    if not same:
        if not (blo <= mid <= bhi):
            return _level_block_plain(x, a, e, clo0, chi0, min_count, rec, row)
        r = _banded_pass(x, a, e, blo, mid, bhi)
    _store(rec, row, _IT, r)
    slo, qlo, nlo, shi, qhi, nhi, nabove = r[0], r[1], r[2], r[3], r[4], r[5], r[6]
    if nlo >= min_count:
        clo = slo / nlo
    if nhi >= min_count:
        chi = shi / nhi
    rec[row, _FRAC] = nabove / (e - a)
    rec[row, _SD] = _pooled_sd(slo, qlo, nlo, shi, qhi, nhi, min_count)
    return clo, chi


@njit(cache=True, nogil=True)
def _store(rec, row, col, r):
    """Write one iteration's counts, means and brackets into ``rec[row]``."""
    rec[row, col + _NLO] = r[2]
    rec[row, col + _NHI] = r[5]
    rec[row, col + _MLO] = r[0] / r[2] if r[2] > 0 else np.nan
    rec[row, col + _MHI] = r[3] / r[5] if r[5] > 0 else np.nan
    rec[row, col + _LB] = r[7]
    rec[row, col + _LA] = r[8]
    rec[row, col + _HB] = r[11]
    rec[row, col + _HA] = r[12]
    if col == _IT:
        rec[row, _MB] = r[9]
        rec[row, _MA] = r[10]


@njit(cache=True, nogil=True)
def _level_block_plain(x, a, e, clo, chi, min_count, rec, row):
    """:func:`block_levels_serial`'s per-block body (:func:`_two_pass_levels`), for levels
    that are not ordered; its record has NaN brackets (never replayed).  Returns the
    carried levels."""
    clo, chi, slo, qlo, nlo, shi, qhi, nhi, nabove = _two_pass_levels(x, a, e, clo, chi, min_count)
    rec[row, :] = np.nan
    if not np.isnan(x[a:e]).any():
        rec[row, _MIN] = x[a:e].min()
        rec[row, _MAX] = x[a:e].max()
    rec[row, _IT + _NLO] = nlo
    rec[row, _IT + _NHI] = nhi
    rec[row, _FRAC] = nabove / (e - a)
    rec[row, _SD] = _pooled_sd(slo, qlo, nlo, shi, qhi, nhi, min_count)
    return clo, chi


@njit(cache=True, nogil=True)
def levels_run(x, block, lo0, hi0, min_count, b_lo, b_hi, rec):
    """Records of the blocks ``b_lo <= b < b_hi`` into ``rec`` (n_blocks, 22), the levels
    carried from block to block like :func:`block_levels_serial`, starting from the
    guess ``(lo0, hi0)`` at ``b_lo``.  Runs of blocks are independent: call it for
    several runs at once, then :func:`levels_walk`."""
    n = x.shape[0]
    clo = lo0
    chi = hi0
    for b in range(b_lo, b_hi):
        e = min(n, (b + 1) * block)
        clo, chi = _level_block(x, b * block, e, clo, chi, min_count, rec, b)


@njit(cache=True)
def _replay(rec, row, clo, chi, min_count):
    """The levels a block's record gives from the true carried levels ``(clo, chi)``.

    Returns ``(ok, clo, chi)``: ``ok`` is true when every band edge and the second mid
    level computed from the true levels (same expressions as the serial kernel) fall in
    the record's brackets, so the serial kernel selects the same samples as the record;
    then ``clo, chi`` are the levels it carries on.
    """
    ok = True
    for col in (0, _IT):
        gap = chi - clo
        blo = clo + 0.25 * gap
        bhi = chi - 0.25 * gap
        ok &= rec[row, col + _LB] < blo <= rec[row, col + _LA]
        ok &= rec[row, col + _HB] <= bhi < rec[row, col + _HA]
        if col == _IT:
            mid = 0.5 * (clo + chi)
            ok &= rec[row, _MB] <= mid < rec[row, _MA]
        if rec[row, col + _NLO] >= min_count:
            clo = rec[row, col + _MLO]
        if rec[row, col + _NHI] >= min_count:
            chi = rec[row, col + _MHI]
    return ok, clo, chi


@njit(cache=True, nogil=True)
def new_level_records(n, block):
    """Empty records (n_blocks, 22) for :func:`levels_run`."""
    return np.empty(((n + block - 1) // block, _NCOL))


def block_extremes(rec):
    """(n_blocks,) minimum and maximum of each block's samples (NaN where a block holds
    a NaN) from the records of :func:`levels_run`."""
    return rec[:, _MIN], rec[:, _MAX]


@njit(cache=True, nogil=True)
def levels_walk(x, block, lo0, hi0, min_count, rec):
    """Exactly :func:`block_levels_serial` (same outputs, bit for bit) from the records
    of :func:`levels_run` (every block recorded, by runs started from ``(lo0, hi0)``).

    The serial kernel carries the levels from block to block, but a block's result
    depends on the carried levels only through which samples each of its two
    iterations selects.  The walk carries the true levels through the records
    (:func:`_replay`, no sample read) and recomputes a block only when a true band edge
    falls outside its recorded brackets: at most a few blocks after the start of each
    run (once a block's selection agrees, the run carried the true levels from there).
    Returns ``(lo, hi, frac_hi, sd)`` as :func:`block_levels_serial`.
    """
    n = x.shape[0]
    nb = rec.shape[0]
    lo = np.empty(nb)
    hi = np.empty(nb)
    frac_hi = np.empty(nb)
    sd = np.empty(nb)
    clo = lo0
    chi = hi0
    for b in range(nb):
        ok, clo_new, chi_new = _replay(rec, b, clo, chi, min_count)
        if not ok:  # recompute from the true levels (the record becomes the serial one)
            clo_new, chi_new = _level_block(
                x, b * block, min(n, (b + 1) * block), clo, chi, min_count, rec, b
            )
        clo = clo_new
        chi = chi_new
        lo[b] = clo if rec[b, _IT + _NLO] >= min_count else np.nan
        hi[b] = chi if rec[b, _IT + _NHI] >= min_count else np.nan
        frac_hi[b] = rec[b, _FRAC]
        sd[b] = rec[b, _SD]
    return lo, hi, frac_hi, sd


@njit(cache=True, nogil=True)
def rc_range(x, k_lo, k_hi, block, open_b, inv_b, max_out):
    """The windows ``k_lo <= k < k_hi`` of :func:`rc_ratios_serial`: the same tests,
    the same ratios in the same order, at most ``max_out`` of each kind.

    The window ``u[k-4..k]`` is a function of ``k`` alone, so a range can start
    anywhere (the four samples before it only fill the window): the ratios of
    ``rc_ratios_serial(x[:k1])`` are those of consecutive ranges covering ``[0, k1)``,
    concatenated and cut to ``max_out``.
    """
    strict = np.empty(max_out)
    slow = np.empty(max_out)
    m = 0
    ms = 0
    k_first = max(k_lo, 4)
    k_hi = min(k_hi, x.shape[0])
    if k_hi <= k_first:
        return strict[:0], slow[:0]
    u0 = u_at(x, k_first - 4, block, open_b, inv_b)
    u1 = u_at(x, k_first - 3, block, open_b, inv_b)
    u2 = u_at(x, k_first - 2, block, open_b, inv_b)
    u3 = u_at(x, k_first - 1, block, open_b, inv_b)
    ks, ke, o0, so, i0, si = _segment(k_first, block, open_b, inv_b)
    for k in range(k_first, k_hi):
        if k >= ke:
            ks, ke, o0, so, i0, si = _segment(k, block, open_b, inv_b)
        d = k - ks
        u4 = (x[k] - (o0 + so * d)) * (i0 + si * d)
        # the serial kernel's two tests; both need 0.05 < u2 < 0.95, which almost every
        # window (samples at a level) fails at once
        if 0.05 < u2 < 0.95:
            kind, r = _rc_window(u0, u1, u2, u3, u4)
            m, ms = _keep_ratio(strict, slow, m, ms, kind, r)
        u0 = u1
        u1 = u2
        u2 = u3
        u3 = u4
    return strict[:m], slow[:ms]
