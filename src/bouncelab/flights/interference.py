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
is clearly there (:func:`interference_gate`): on a clean channel nothing changes.

Pure numpy, in pieces of ``PIECE`` samples, so that memory stays a few arrays of one
piece beside the copy that is returned.
"""

from __future__ import annotations

import numpy as np

WINDOW_S = 1e-3  # running mean of the residuals: 1/20 of a 50 Hz period (0.4 % error)
SLOW_S = 0.1  # the slow part left to the level tracking: 5 periods at 50 Hz, 6 at 60 Hz
GUARD_MIN = 4  # samples left out on each side of a crossing of the mid level (the edge)
TAIL_REL = 0.002  # ... and after it, until an RC tail has decayed to this share of the gap
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
    of the gap, its decay per sample ``q`` the median of :func:`decay_ratios`."""
    q = float(np.clip(np.median(ratios), 0.0, 0.99)) if ratios.size else 0.0
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
    """:func:`_smooth` of the used samples; ``per_state``: of each state's own used
    samples, each applied to its own state's samples.  ``(n,)`` array, or None when no
    window is full enough.

    Why per state: an open circuit is a high impedance and picks up hum that the closed
    one (a short) does not.  One estimate from both states sees half the hum and
    subtracts it from both; with a 50 Hz hum of 10 % of the gap on the open level only,
    ``raw/sweep_g0-4`` lost a fifth of its flights (12104 -> 9718) and read the RC
    time constant as 26 us instead of 9.  Only for such a hum (:func:`hum_per_state`):
    where both states carry the same hum, one estimate from all the samples is the
    better one (at 5 % of the gap on both, 0.4 against 3.2 us median error).  A state
    without a full window anywhere in the piece takes the other state's estimate."""
    if not per_state:
        return _smooth(resid, used, w)
    est = {state: _smooth(resid, used & (up == state), w) for state in (False, True)}
    if est[False] is None and est[True] is None:
        return None
    lo_est = est[False] if est[False] is not None else est[True]
    hi_est = est[True] if est[True] is not None else est[False]
    return np.where(up, hi_est, lo_est)


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
    est = _estimate(resid, used, up, w, per_state)
    if est is None:
        return np.zeros(n), used
    odd = np.abs(resid - est) > max(OUTLIER_K * noise_v, OUTLIER_REL * gap)
    used &= ~_dilate(odd, GUARD_MIN, guard)
    resid -= _state_offsets(resid - est, up, used, state_block)
    est2 = _estimate(resid, used, up, w, per_state)
    est = est if est2 is None else est2
    slow, cs = _running_mean(est, np.ones(n), _window(sample_rate_hz, SLOW_S, w) // 2)
    return est - slow / cs, used


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
    guard = guard_samples(np.concatenate([decay_ratios(x[a:b], lo, hi) for a, b in windows]))
    read = (x, windows, lo, hi, noise_v, sample_rate_hz, guard, slow)
    if not interference_gate(_windows_rms(*read, False)[2], hi - lo, noise_v, w):
        return x, np.zeros(nb)
    per_state = hum_per_state(_windows_rms(*read, True)[:2])
    margin = slow // 2 + w + guard
    out = np.array(x, dtype=np.float64)
    sq_b = np.zeros(nb)
    cnt_b = np.zeros(nb)
    for a, b, a0, b0 in _pieces(n, margin, piece):
        fast, used = fast_interference(x[a:b], lo, hi, noise_v, sample_rate_hz, guard, per_state)
        f = fast[a0 - a : b0 - a]
        u = used[a0 - a : b0 - a]
        out[a0:b0] -= f
        blk = np.arange(a0, b0) // block
        sq_b += np.bincount(blk, weights=np.where(u, f * f, 0.0), minlength=nb)
        cnt_b += np.bincount(blk, weights=u.astype(np.float64), minlength=nb)
    return out, np.sqrt(sq_b / np.maximum(cnt_b, 1.0))
