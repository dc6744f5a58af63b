"""Numba kernels of the continuity detection: block levels, RC constant, edges.

Each kernel is one pass over a 1-D float array of samples and keeps O(1) state besides
its (small) outputs, so a 20-minute recording needs nothing beyond the samples.
Time is in samples here (sample ``k`` is at ``t = k``); the Python side converts.

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
def block_levels(x, block, lo0, hi0, min_count):
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
        slo = 0.0
        shi = 0.0
        qlo = 0.0
        qhi = 0.0
        nlo = 0
        nhi = 0
        for _ in range(2):
            gap = chi - clo
            blo = clo + 0.25 * gap
            bhi = chi - 0.25 * gap
            mid = 0.5 * (clo + chi)
            slo = 0.0
            shi = 0.0
            qlo = 0.0
            qhi = 0.0
            nlo = 0
            nhi = 0
            nabove = 0
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
            frac_hi[b] = nabove / (e - a)
            if nlo >= min_count:
                clo = slo / nlo
            if nhi >= min_count:
                chi = shi / nhi
        ss = 0.0
        cnt = 0
        if nlo >= min_count:
            lo[b] = clo
            ss += qlo - slo * slo / nlo
            cnt += nlo - 1
        if nhi >= min_count:
            hi[b] = chi
            ss += qhi - shi * shi / nhi
            cnt += nhi - 1
        if cnt > 0:
            sd[b] = math.sqrt(max(ss, 0.0) / cnt)
    return lo, hi, frac_hi, sd


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
def rc_ratios(x, block, open_b, inv_b, max_out):
    """Decay ratios right after clean edges, to estimate the RC constant q = exp(-1/tau).

    After a takeoff inside ``(k-1, k]`` the filtered signal only decays, so
    ``u[k+1] = q u[k]`` exactly (and ``1-u`` likewise after a landing).  A ratio is
    taken only at clean, held edges: two samples at the old level (within 0.1 of the
    gap), the first sample after the edge between 0.3 and 0.95 of the way (0.05-0.7
    for landings), the next moving on, and the one after that within 0.1 of the new
    level (so a chatter impact or a one-sample contact does not spoil the ratio).
    Returns up to ``max_out`` ratios.
    """
    n = x.shape[0]
    out = np.empty(max_out)
    m = 0
    if n < 5:
        return out[:0]
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
        # takeoff after a held contact, then two samples that settle towards open
        if u[0] > 0.9 and u[1] > 0.9 and 0.3 < u[2] < 0.95 and u[3] < u[2] and u[4] < 0.1:
            if m < max_out:
                out[m] = u[3] / u[2]
                m += 1
        # landing after a held opening, then two samples that settle towards contact
        elif u[0] < 0.1 and u[1] < 0.1 and 0.05 < u[2] < 0.7 and u[3] > u[2] and u[4] > 0.9:
            if m < max_out:
                out[m] = (1.0 - u[3]) / (1.0 - u[2])
                m += 1
    return out[:m]


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


@njit(cache=True)
def detect_edges(x, block, open_b, inv_b, sdz_b, q, thr_min, thr_max, d_prior, glitch_k):
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
        if state == 0:
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
        else:
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
