"""Fast additive interference (mains hum) on a continuity channel: found and subtracted.

A continuity circuit in a teaching lab picks up mains hum (50 or 60 Hz and harmonics)
and, with it, a drive-coupled ripple.  The level tracking of :mod:`.detect` follows
drift over blocks of 0.2 s, not a ripple of 20 ms; and a ripple of a few per cent of the
level gap corrupts the RC estimate (the decay ratios after an edge no longer decay to
zero) and raises the detection threshold, so that whole contacts are lost and flights
merge (a 50 Hz hum of 10 % of the gap lost half of the flights of ``raw/sweep_g0-4``).

The interference is smooth at the scale of a sample, the switch is not: away from the
edges, the samples minus their level (open or contact) are the interference plus white
noise.  A running mean of those residuals over ``WINDOW_S`` (edges and their
neighbourhood left out, bridged by interpolation) estimates it; its slow part (a running
mean over ``SLOW_S``, a whole number of mains periods at 50 and 60 Hz) is left to the
level tracking, which already follows drift.  The fast part is subtracted only when it
is clearly there (:func:`interference_gate`): on a clean channel nothing changes.  What
is subtracted is the running mean's spectral lines (:func:`find_lines`), fitted to the
residuals block by block (:func:`fit_lines`): where edges are dense the running mean's
bridges miss the hum, a fit of its lines does not.

Pure numpy, in pieces of ``PIECE`` samples, so that memory stays a few arrays of one
piece beside the copy that is returned.
"""

from __future__ import annotations

import numpy as np
from scipy import fft as sp_fft

WINDOW_S = 1e-3  # running mean of the residuals: 1/20 of a 50 Hz period (0.4 % error)
SLOW_S = 0.1  # the slow part left to the level tracking: 5 periods at 50 Hz, 6 at 60 Hz
GUARD_MIN = 4  # samples left out on each side of a crossing of the mid level (the edge)
TAIL_REL = 0.002  # ... and after it, until an RC tail has decayed to this share of the gap
MIN_RATIOS = 8  # decay ratios the guard needs; fewer: the decay is not measured
EDGE_REL = 0.25  # residuals beyond this share of the gap are edges or glitches
OUTLIER_K = 6.0  # the second pass leaves out residuals this many noise sigmas ...
OUTLIER_REL = 0.01  # ... or this share of the gap off the first estimate
STATE_BLOCK_S = 1.0  # blocks of the levels' own offsets: many rests, at any hum phase
MIN_STATE = 32  # used samples a state needs in a block for its own offset
GATE_REL = 0.004  # subtract when the fast part's rms exceeds this share of the gap ...
GATE_K = 5.0  # ... and this many times what white noise leaves in the running mean
GATE_WINDOWS = 8  # windows the gate reads ...
GATE_WINDOW_S = 0.4  # ... of this length each (at least four slow windows)
STATE_RATIO = 0.5  # each state its own estimate when one state's hum is below this share
PIECE = 1 << 20  # samples per piece
LINE_MIN_HZ = 5.0  # spectral lines looked for above this (slower: the level tracking's)
LINE_MAX_HZ = 0.5 / WINDOW_S  # ... and up to this: the running mean they are read on
#   passes 64 % of a line there, nothing at twice it (harmonics to the 9th of 50 Hz)
LINE_MAX = 12  # lines at most (50 or 60 Hz and harmonics, a drive-coupled ripple)
LINE_STOP_REL = 0.001  # a line needs this share of the gap, amplitude ...
LINE_STOP_FIRST = 0.02  # ... and this share of the strongest line's
LINE_MIN_S = 1.0  # pieces shorter than this keep the running mean (lines unresolved)
LINE_BLOCK_S = 0.2  # blocks of the line fit, overlapping by half (10 periods at 50 Hz)
LINE_APART_S = 1.5  # lines closer than this many cycles per block are one (1.5 / 0.2 s)
LINE_MIN_R2 = 0.9  # share of the running mean's variance the lines must explain
LINE_RCOND = 1e-3  # singular values of a block's normalised design below this share unused
LINE_RCOND_STATE = 0.01  # ... in a fit of one state's samples alone (fewer, in clusters)


def _window(sample_rate_hz: float, seconds: float, minimum: int) -> int:
    """Odd window length, samples, of ``seconds`` at ``sample_rate_hz``."""
    return max(minimum, int(round(seconds * sample_rate_hz))) | 1


def _running_mean(values: np.ndarray, weights: np.ndarray, half: int) -> tuple:
    """Weighted running sums over ``[i - half, i + half]``: (sum of w v, sum of w)."""
    n = values.shape[0]
    cv = np.concatenate(([0.0], np.cumsum(values * weights)))
    cw = np.concatenate(([0.0], np.cumsum(weights)))
    i = np.arange(n)
    a = np.maximum(i - half, 0)
    b = np.minimum(i + half + 1, n)
    return cv[b] - cv[a], cw[b] - cw[a]


def decay_ratios(x: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """Ratios of the second and first steps of the samples after each crossing of the mid
    level whose first sample is more than 0.3 of the gap from its level: an RC decay per
    sample each (``(x[k+2] - x[k+1]) / (x[k+1] - x[k])`` is ``q`` for a decay towards
    any level).  Their median is a rough decay (:func:`guard_samples`); an interference
    of a few per cent of the gap shifts single ratios either way, not their median.

    Why steps, not residuals from the global levels: a slow drift of the levels, which
    the global levels do not follow, made those ratios near 1 (a drift of 30 % of the
    gap: the guard grew to 618 samples, most of every flight was left out, and a hum of
    5 % of the gap was not estimated there: 72 of 899 flights lost)."""
    x = np.asarray(x, dtype=np.float64)
    up = x > 0.5 * (lo + hi)
    k = np.flatnonzero(up[1:] != up[:-1]) + 1  # first sample in the new state
    k = k[k + 2 < x.shape[0]]
    level = np.where(up[k], hi, lo)
    d1 = x[k + 1] - x[k]
    d2 = x[k + 2] - x[k + 1]
    ok = (np.abs(x[k] - level) > 0.3 * (hi - lo)) & (up[k + 1] == up[k]) & (up[k + 2] == up[k])
    ok &= d1 != 0.0
    return d2[ok] / d1[ok]


def guard_samples(ratios: np.ndarray) -> int:
    """Samples left out after a crossing: the edge, and an RC tail down to ``TAIL_REL``
    of the gap, its decay per sample ``q`` the median of :func:`decay_ratios`.

    Only ratios inside (-1, 1) are a decay; fewer than ``MIN_RATIOS`` of them measure
    nothing, and ``GUARD_MIN`` is kept.  Why: on a fast front end few crossings land
    mid-sample, and those that do are often chatter, whose next samples are not a tail.
    One such ratio (3.4) once stood for the decay of a whole gain-stepped side: the
    guard grew to 620 samples, nearly every sample was left out, and a hum of 6 % of the
    gap was not subtracted (flight times 8-20 us off instead of 1)."""
    ratios = np.asarray(ratios, dtype=np.float64)
    ratios = ratios[np.abs(ratios) < 1.0]
    if ratios.size < MIN_RATIOS:
        return GUARD_MIN
    q = float(np.clip(np.median(ratios), 0.0, 0.99))
    if q <= 0.0:
        return GUARD_MIN
    return max(GUARD_MIN, int(np.ceil(np.log(TAIL_REL) / np.log(q))) + 1)


def _dilate(mask: np.ndarray, before: int, after: int) -> np.ndarray:
    """``mask`` widened by ``before`` samples to the left and ``after`` to the right."""
    n = mask.shape[0]
    at = np.flatnonzero(mask)
    d = np.zeros(n + 1, dtype=np.int64)
    np.add.at(d, np.clip(at - before, 0, n), 1)
    np.add.at(d, np.clip(at + after + 1, 0, n), -1)
    return np.cumsum(d[:n]) > 0


def _smooth(resid: np.ndarray, used: np.ndarray, w: int) -> np.ndarray | None:
    """Running mean of ``resid`` over the ``used`` samples in windows of ``w``, bridged by
    linear interpolation where a window holds too few of them; None if none does."""
    s, c = _running_mean(resid, used.astype(np.float64), w // 2)
    idx = np.flatnonzero(c >= max(3, w // 4))
    if idx.size == 0:
        return None
    return np.interp(np.arange(resid.shape[0]), idx, s[idx] / c[idx])


def _estimate(resid: np.ndarray, used: np.ndarray, up: np.ndarray, w: int, per_state: bool):
    """:func:`_smooth` of the used samples: ``[est]``; ``per_state``: of each state's
    own used samples, ``[lower state's, upper state's]`` (see :func:`_combine`).  Each
    (n,); None when no window is full enough.

    Why per state: an open circuit is a high impedance and picks up hum that the closed
    one (a short) does not.  One estimate from both states sees half the hum and
    subtracts it from both; with a 50 Hz hum of 10 % of the gap on the open level only,
    ``raw/sweep_g0-4`` lost a fifth of its flights (12104 -> 9718) and read the RC
    time constant as 26 us instead of 9.  Only for such a hum (:func:`hum_per_state`):
    where both states carry the same hum, one estimate from all the samples is the
    better one (at 5 % of the gap on both, 0.4 against 3.2 us median error).  A state
    without a full window anywhere in the piece takes the other state's estimate."""
    if not per_state:
        est = _smooth(resid, used, w)
        return None if est is None else [est]
    est = {state: _smooth(resid, used & (up == state), w) for state in (False, True)}
    if est[False] is None and est[True] is None:
        return None
    lo_est = est[False] if est[False] is not None else est[True]
    hi_est = est[True] if est[True] is not None else est[False]
    return [lo_est, hi_est]


def _combine(ests: list, share_hi: np.ndarray) -> np.ndarray:
    """One estimate (n,) from :func:`_estimate`'s: the one, or the two states' mixed by
    ``share_hi`` (n,), how far each sample lies from the lower level towards the upper
    (0-1).  Why mixed: the hum of a level is picked up in proportion to how far the
    circuit is in that state, and a front end slower than the sampling passes through
    every share; at each sample's own state alone, a hum on the open level through a
    100 us front end lost up to 60 % of the flights."""
    if len(ests) == 1:
        return ests[0]
    return ests[0] + (ests[1] - ests[0]) * share_hi


def _share_hi(x: np.ndarray, lo: float, hi: float, ests: list) -> np.ndarray:
    """Each sample's share (n,) of the way from the lower level to the upper (0-1), read
    off the sample with the interference of :func:`_combine` at that share taken out
    (solved for it): a hum of a fifth of the gap on the upper level alone would
    otherwise read a sample at that level as 0.8 of the way there."""
    gap = hi - lo
    if len(ests) == 1:
        return np.clip((x - lo) / gap, 0.0, 1.0)
    # x = lo + e_lo + (gap + e_hi - e_lo) share, solved for the share
    lo_est, hi_est = ests
    span = gap + hi_est - lo_est
    span = np.where(np.abs(span) > 0.1 * abs(gap), span, 0.1 * gap)
    return np.clip((x - lo - lo_est) / span, 0.0, 1.0)


def _state_offsets(resid, up, used, block):
    """Per block and per state (open, contact), the mean of the used residuals, as an
    (n,) array to subtract: the two levels' own errors (the global levels of the
    two-means split carry the samples caught on edges), which would otherwise alternate
    with the state and pass for a fast interference.  A block with fewer than
    ``MIN_STATE`` used samples of a state takes the state's median offset."""
    n = resid.shape[0]
    blk = np.arange(n) // block
    nb = int(blk[-1]) + 1 if n else 0
    out = np.zeros(n)
    for state in (False, True):
        m = used & (up == state)
        cnt = np.bincount(blk, weights=m.astype(np.float64), minlength=nb)
        tot = np.bincount(blk, weights=np.where(m, resid, 0.0), minlength=nb)
        ok = cnt >= MIN_STATE
        fill = float(np.median(tot[ok] / cnt[ok])) if ok.any() else 0.0
        off = np.where(ok, tot / np.maximum(cnt, 1.0), fill)
        out = np.where(up == state, off[blk], out)
    return out


def fast_interference(
    x: np.ndarray,
    lo: float,
    hi: float,
    noise_v: float,
    sample_rate_hz: float,
    guard: int = GUARD_MIN,
    per_state: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """Fast part of the interference on one piece of a two-level channel.

    Two passes: the first leaves out the samples near a crossing of the mid level; the
    second also leaves out the samples that stand out of the first estimate by more
    than ``OUTLIER_K`` noise sigmas (or ``OUTLIER_REL`` of the gap), widened like the
    crossings: a short contact seen through a slow RC front end never crosses the mid
    level, and its excursion is no interference.

    Parameters
    ----------
    x : (n,) float array, volts.
    lo, hi : the two levels, volts (``lo < hi``), from the global two-means split.
    noise_v : white-noise standard deviation per sample, volts.
    sample_rate_hz : sampling rate.
    guard : samples left out after each crossing (:func:`guard_samples`); ``GUARD_MIN``
        before it.
    per_state : estimate each state's interference from its own samples
        (:func:`_estimate`) instead of one from both.

    Returns
    -------
    fast : (n,) float, the interference minus its running mean over ``SLOW_S``, volts.
    used : (n,) bool, the samples whose residuals entered the estimate.
    """
    ests, _, used, _ = _running_estimate(x, lo, hi, noise_v, sample_rate_hz, guard, per_state)
    return _fast_part(x, lo, hi, ests, sample_rate_hz), used


def _fast_part(x, lo, hi, ests, sample_rate_hz) -> np.ndarray:
    """The estimates ``ests`` (:func:`_estimate`, :func:`fit_lines`) mixed by each sample's
    share (:func:`_combine`, :func:`_share_hi`), minus their slow part: (n,) volts."""
    return _minus_slow(_combine(ests, _share_hi(x, lo, hi, ests)), sample_rate_hz)


def _minus_slow(est: np.ndarray, sample_rate_hz: float) -> np.ndarray:
    """``est`` minus its running mean over ``SLOW_S`` (left to the level tracking)."""
    n = est.shape[0]
    w = _window(sample_rate_hz, WINDOW_S, 5)
    slow, cs = _running_mean(est, np.ones(n), _window(sample_rate_hz, SLOW_S, w) // 2)
    return est - slow / cs


def _running_estimate(x, lo, hi, noise_v, sample_rate_hz, guard, per_state):
    """The two passes of :func:`fast_interference`: ``(ests, resid, used, up)``: the
    running-mean estimates of :func:`_estimate` (``[zeros]`` when no window is full
    enough), the residuals from the levels (their per-state block offsets taken out),
    the samples used, and the state (above the mid level) of each sample; each (n,)."""
    x = np.asarray(x, dtype=np.float64)
    n = x.shape[0]
    gap = hi - lo
    up = x > 0.5 * (lo + hi)
    resid = x - np.where(up, hi, lo)
    near = _dilate(up[1:] != up[:-1], GUARD_MIN - 1, guard)
    away = ~np.append(near, near[-1:] if n > 1 else [])
    w = _window(sample_rate_hz, WINDOW_S, 5)
    state_block = _window(sample_rate_hz, STATE_BLOCK_S, w)
    resid -= _state_offsets(resid, up, away, state_block)
    used = (np.abs(resid) < EDGE_REL * gap) & away
    resid -= _state_offsets(resid, up, used, state_block)
    ests = _estimate(resid, used, up, w, per_state)
    if ests is None:
        return [np.zeros(n)], resid, used, up
    est = _combine(ests, _share_hi(x, lo, hi, ests))
    odd = np.abs(resid - est) > max(OUTLIER_K * noise_v, OUTLIER_REL * gap)
    used &= ~_dilate(odd, GUARD_MIN, guard)
    resid -= _state_offsets(resid - est, up, used, state_block)
    ests2 = _estimate(resid, used, up, w, per_state)
    return (ests if ests2 is None else ests2), resid, used, up


def find_lines(est: np.ndarray, sample_rate_hz: float, gap_v: float) -> np.ndarray:
    """Frequencies (Hz, shape (m,), strongest first) of the spectral lines of an
    interference estimate ``est`` (n,), volts: mains hum and its harmonics, or a ripple.

    The strongest peak of the Hann-windowed spectrum between ``LINE_MIN_HZ`` and
    ``LINE_MAX_HZ``, its frequency refined by a parabola through the log magnitudes of
    its bin and the two beside it (a few thousandths of a bin for a Hann window), then
    the frequencies within ``LINE_APART_S / LINE_BLOCK_S`` Hz of it masked (a block of
    :func:`fit_lines` would not tell them apart: sidebands of the running mean's errors,
    which follow the drive), up to ``LINE_MAX`` lines; a line below ``LINE_STOP_REL`` of
    the gap or ``LINE_STOP_FIRST`` of the strongest (amplitudes) ends the list."""
    n = est.shape[0]
    if n < 16:
        return np.zeros(0)
    win = np.hanning(n)
    n_fft = sp_fft.next_fast_len(n, real=True)  # a piece plus margins is no fast length
    amp = 2.0 * np.abs(sp_fft.rfft((est - est.mean()) * win, n_fft)) / win.sum()
    df = sample_rate_hz / n_fft
    f_bin = np.arange(amp.shape[0]) * df
    free = (f_bin >= LINE_MIN_HZ) & (f_bin <= LINE_MAX_HZ)
    free[-1] = False
    out = []
    first = 0.0
    for _ in range(LINE_MAX):
        if not free[1:].any():
            break
        i = int(np.argmax(np.where(free, amp, -1.0)))
        if amp[i] < max(LINE_STOP_REL * abs(gap_v), LINE_STOP_FIRST * first):
            break
        first = first or float(amp[i])
        a, b, c = np.log(np.maximum(amp[i - 1 : i + 2], 1e-300))
        den = a - 2.0 * b + c
        shift = 0.5 * (a - c) / den if den < 0 else 0.0
        out.append((i + float(np.clip(shift, -0.5, 0.5))) * df)
        # the Hann main lobe (2 bins each side), and lines a block's fit cannot tell apart
        apart = max(4, int(np.ceil(LINE_APART_S / LINE_BLOCK_S / df)))
        free[max(0, i - apart) : i + apart + 1] = False
    return np.array(out)


def fit_lines(resid, used, up, freqs, sample_rate_hz, fallbacks) -> list:
    """The lines ``freqs`` (Hz) fitted to the residuals ``resid`` (n,) on the ``used``
    samples: least squares over blocks of ``LINE_BLOCK_S`` overlapping by half (an
    amplitude and phase per line and block, and an offset per state, which is the
    levels' and is not returned), cross-faded by triangles so that the estimate has no
    steps.  ``fallbacks``: :func:`_estimate`'s running means, one (both states fitted
    together) or two (each state, ``up``, its own fit); one stands in for its fit where
    a block holds too few of its samples.  A list like ``fallbacks``, each (n,) volts
    (for :func:`_combine`).

    Why: the running mean bridges every edge's neighbourhood by a straight line; where
    edges are dense (a body riding or chattering, a slow front end's long guard) those
    bridges span much of a 180 Hz period, and the running mean missed up to a third of
    a 60 Hz hum with its third harmonic (on a 100 us front end).  A line's fit needs
    only its phases covered."""
    n = resid.shape[0]
    half = max(1, int(round(0.5 * LINE_BLOCK_S * sample_rate_hz)))
    w_of = 2.0 * np.pi * np.asarray(freqs, dtype=np.float64) / sample_rate_hz
    per_state = len(fallbacks) == 2
    out = [np.zeros(n) for _ in fallbacks]
    weight = np.zeros(n)
    # every block sees the lines at the same offsets from its centre: one table
    phase = np.outer(np.arange(-half, half), w_of)
    table = np.concatenate((np.cos(phase), np.sin(phase)), axis=1)
    for centre in range(0, n + half, half):
        a, b = max(0, centre - half), min(n, centre + half)
        if b <= a:
            continue
        k = np.arange(a, b)
        basis = table[a - centre + half : b - centre + half]
        st, u, r = up[a:b], used[a:b], resid[a:b]
        groups = (~st, st) if per_state else (np.ones(b - a, dtype=bool),)
        models = []
        for rows, fallback in zip(groups, fallbacks, strict=True):
            models.append(fallback[a:b])
            fit = rows & u
            # beside the lines, an offset per state fitted (the levels' errors over the
            # block, not returned)
            offsets = [m for m in (fit & ~st, fit & st) if m.any()]
            design = np.concatenate([basis] + [m[:, None].astype(np.float64) for m in offsets], 1)
            if np.count_nonzero(fit) < 4 * design.shape[1]:
                continue
            d = design[fit]
            norm = np.maximum(np.sqrt(np.sum(d * d, axis=0)), 1e-12)
            # directions the fitted samples hardly see are left out (coefficient 0), not
            # extrapolated: a state seen in a few short contacts, all at one phase
            rcond = LINE_RCOND_STATE if per_state else LINE_RCOND
            coef = np.linalg.lstsq(d / norm, r[fit], rcond=rcond)[0] / norm
            models[-1] = basis @ coef[: basis.shape[1]]
        tri = 1.0 - np.abs(k - centre) / half
        for acc, model in zip(out, models, strict=True):
            acc[a:b] += tri * model
        weight[a:b] += tri
    return [acc / np.maximum(weight, 1e-12) for acc in out]


def _pieces(n: int, margin: int, piece: int):
    """``(a, b, a0, b0)``: piece ``[a0, b0)`` computed on ``[a, b)`` with its margins."""
    for a0 in range(0, n, piece):
        b0 = min(n, a0 + piece)
        yield max(0, a0 - margin), min(n, b0 + margin), a0, b0


def interference_gate(rms_v: float, gap_v: float, noise_v: float, window: int) -> bool:
    """Whether a fast interference of rms ``rms_v`` is clearly there.

    White noise of ``noise_v`` per sample leaves about ``noise_v / sqrt(window)`` in the
    running mean; the interference must stand ``GATE_K`` times above that and above
    ``GATE_REL`` of the level gap (below it, detection loses nothing measurable).
    """
    floor = max(GATE_REL * abs(gap_v), GATE_K * noise_v / np.sqrt(window))
    return bool(rms_v > floor)


def _windows(n: int, length: int, count: int) -> list[tuple[int, int]]:
    """``count`` windows ``[a, a + length)`` spread evenly over ``n`` samples (one window
    of all of them when they do not fit)."""
    if n <= length * count:
        return [(0, n)]
    starts = np.linspace(0, n - length, count).astype(np.int64)
    return [(int(a), int(a) + length) for a in starts]


def _windows_rms(x, windows, lo, hi, noise_v, sample_rate_hz, guard, slow, per_state):
    """rms of :func:`fast_interference` over the used samples of ``windows`` (each away
    from its ends, where the ``slow`` window, samples, is cut short), volts, shape (3,):
    on the lower level's samples, on the upper level's, on both."""
    sq = np.zeros(3)
    cnt = np.zeros(3)
    for a, b in windows:
        fast, used = fast_interference(x[a:b], lo, hi, noise_v, sample_rate_hz, guard, per_state)
        inner = slice(min(slow, (b - a) // 4), max(b - a - slow, 3 * (b - a) // 4))
        f, u = fast[inner], used[inner]
        up = np.asarray(x[a:b][inner], dtype=np.float64) > 0.5 * (lo + hi)
        for i, m in enumerate((u & ~up, u & up, u)):
            sq[i] += float(np.sum(f[m] ** 2))
            cnt[i] += float(np.count_nonzero(m))
    return np.sqrt(sq / np.maximum(cnt, 1.0))


def hum_per_state(rms_levels) -> bool:
    """Whether the two levels carry clearly different interference (rms of each level's
    own estimate, volts): one below ``STATE_RATIO`` of the other.  An open circuit is a
    high impedance and picks up hum that a closed one does not."""
    a, b = (float(v) for v in rms_levels)
    return min(a, b) < STATE_RATIO * max(a, b)


def line_interference(x, lo, hi, noise_v, sample_rate_hz, guard=GUARD_MIN, per_state=False):
    """:func:`fast_interference`, with the running mean replaced by its spectral lines
    (:func:`find_lines`) fitted to the residuals (:func:`fit_lines`) where the piece is
    long enough to resolve them (``LINE_MIN_S``) and they explain at least
    ``LINE_MIN_R2`` of the running mean's variance on the used samples; the running mean
    where not, or where a block lacks the samples to fit them.  ``(fast, used)``, both
    (n,)."""
    ests, resid, used, up = _running_estimate(x, lo, hi, noise_v, sample_rate_hz, guard, per_state)
    running = _fast_part(x, lo, hi, ests, sample_rate_hz)
    if x.shape[0] < LINE_MIN_S * sample_rate_hz or not used.any():
        return running, used
    freqs = find_lines(running, sample_rate_hz, hi - lo)
    if not freqs.size:
        return running, used
    lines = fit_lines(resid, used, up, freqs, sample_rate_hz, ests)
    fast = _fast_part(x, lo, hi, lines, sample_rate_hz)
    # lines must carry the running mean: a mains hum does (R^2 0.98-1.00 on the hum
    # grid), the chatter of a body shaken at rest by a random vibration does not (-1.2
    # and 0.61 on the blind ool_vibration cases), and its lines are not to be subtracted
    a, b = running[used], fast[used]
    explained = 1.0 - float(np.var(a - b)) / max(float(np.var(a)), 1e-300)
    return (fast if explained >= LINE_MIN_R2 else running), used


def remove_interference(
    x: np.ndarray,
    lo: float,
    hi: float,
    noise_v: float,
    sample_rate_hz: float,
    block: int,
    piece: int = PIECE,
) -> tuple[np.ndarray, np.ndarray]:
    """The channel with its fast interference subtracted, when the gate says it is there.

    The gate (:func:`interference_gate`) reads ``GATE_WINDOWS`` windows of
    ``GATE_WINDOW_S`` spread over the recording (mains hum does not come and go), so
    that a clean channel costs a few milliseconds; only a channel with interference is
    estimated and corrected throughout, in pieces: each level from its own samples when
    the gate's windows show the levels' interference clearly different
    (:func:`hum_per_state`), else one estimate from both.

    Parameters
    ----------
    x : (n,) array, volts.
    lo, hi : global levels, volts (``lo < hi``).
    noise_v : white-noise standard deviation per sample, volts.
    sample_rate_hz : sampling rate.
    block : samples per level block, for the per-block rms.
    piece : samples per piece (memory).  Each piece takes its own levels' offsets
        (1 s blocks from its start), so the estimate depends a little on it; fixed by
        default, so the result is deterministic.

    Returns
    -------
    x_out : ``x`` itself (not copied) when nothing is subtracted, else a float64 copy.
    rms_block_v : (n_blocks,) float, rms of the subtracted interference per block,
        volts; zeros when nothing is subtracted.
    """
    n = x.shape[0]
    nb = -(-n // block)
    w = _window(sample_rate_hz, WINDOW_S, 5)
    slow = _window(sample_rate_hz, SLOW_S, w)
    length = max(4 * slow, int(GATE_WINDOW_S * sample_rate_hz))
    windows = _windows(n, length, GATE_WINDOWS)
    ratios = np.concatenate([decay_ratios(x[a:b], lo, hi) for a, b in windows])
    if np.count_nonzero(np.abs(ratios) < 1.0) < MIN_RATIOS:  # too few there: all of it
        ratios = decay_ratios(x, lo, hi)
    guard = guard_samples(ratios)
    read = (x, windows, lo, hi, noise_v, sample_rate_hz, guard, slow)
    if not interference_gate(_windows_rms(*read, False)[2], hi - lo, noise_v, w):
        return x, np.zeros(nb)
    per_state = hum_per_state(_windows_rms(*read, True)[:2])
    margin = slow // 2 + w + guard
    out = np.array(x, dtype=np.float64)
    sq_b = np.zeros(nb)
    cnt_b = np.zeros(nb)
    for a, b, a0, b0 in _pieces(n, margin, piece):
        fast, used = line_interference(x[a:b], lo, hi, noise_v, sample_rate_hz, guard, per_state)
        f = fast[a0 - a : b0 - a]
        u = used[a0 - a : b0 - a]
        out[a0:b0] -= f
        blk = np.arange(a0, b0) // block
        sq_b += np.bincount(blk, weights=np.where(u, f * f, 0.0), minlength=nb)
        cnt_b += np.bincount(blk, weights=u.astype(np.float64), minlength=nb)
    return out, np.sqrt(sq_b / np.maximum(cnt_b, 1.0))
