"""Contacts and flights from a continuity channel: levels, polarity, RC constant, edges.

:func:`detect_contacts` is a pure function of a sample array (volts) and a few hints;
it returns a :class:`Detection` with sub-sample edge times in samples.  The heavy work
is in the numba kernels of :mod:`bouncelab.flights.kernels`; this module arranges them.

Rules (docs/flights.md has the full story):

* Interference: given the sampling rate, a fast additive interference (mains hum) is
  looked for on a few windows and, where clearly there, subtracted from the whole
  channel first (:mod:`bouncelab.flights.interference`); a clean channel is untouched.
* Level jumps: after the detection, a level lost or blurred by a gain or supply change
  (:func:`level_jump`) splits the recording at the jump (:func:`refine_cut`), and each
  side is detected on its own; a steady channel is untouched.
* Levels: a global two-means split of (a stride of) the samples starts a per-block
  estimate (blocks of ``block`` samples, 0.1-0.2 s): each level is the mean of the
  samples within a quarter of the gap from it, followed from block to block, and
  linearly interpolated between block centres, so slow baseline drift does not matter.
  A level missing in a block (the body rests, or flies, for the whole block) is the
  other level plus the gap interpolated from the neighbouring blocks.
* Polarity (``contact_level="auto"``): (1) in the intervals where the body is known to
  rest (steps with Gamma < 1) the level held most of the time is contact; else (2) in
  intervals known to be open (a drop test before release) the level held most is open;
  else (3) the level held for less of the recording is contact (in the bouncing region
  contacts are short and flights long; each level has as many dwell segments as the
  other, so a shorter total time means shorter excursions).
* RC constant ``q = exp(-1/tau)`` from the decay ratio of the first samples after clean
  edges (median); ``q = 0`` (no RC model: linear interpolation, the box model) when
  fewer than eight clean ratios exist or the median is below 1e-4.
* Instants, not means: with ``q = 0``, a channel whose edges hardly ever leave a sample
  between the levels (:func:`point_sampled`) has every edge put in the middle of its
  interval, half a sample after the box model's reading.
* Detection threshold on the deconvolved contact fraction ``z``: ``clip(6 sigma_z,
  0.06, 0.45)``; a contact that fills less than that share of one sample interval is
  not seen (about 6 us at 20 kHz with the usual RC front end), and the two flights
  around it merge into one.
* A level held between open and contact (a contact that half-conducts: four or more
  intervals at one partial fraction) is one contact, not one per two samples
  (:func:`kernels._held_reading`); :func:`held_stretches` measures such stretches for
  the extraction's warning.
* A front end that rings before its edges (a sound card's linear-phase anti-alias
  filter; :func:`pre_edge_ringing`) has its ringing taken as noise, and is read again.

Speed (docs/flights.md, "Speed"): every pass over the samples is cut into pieces that
run on ``numba.get_num_threads()`` threads (the kernels release the GIL), and the
pieces are stitched so that the result is bit for bit that of the serial kernels
(``kernels.*_serial``, the definition): the levels pass replays each block's record
with the truly carried levels, the edge pass compares the state each piece started
from (after a warm-up) with the state the previous piece ended in, and reruns a piece
in the rare case they differ.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace

import numba
import numpy as np

from bouncelab.errors import BouncelabError
from bouncelab.flights import kernels
from bouncelab.flights.interference import remove_interference

SLOW_MAD_MAX = 0.05  # largest MAD of the slow-front-end ratios that is read as one RC
Q_RESOLVED = 1.0  # standard errors the median RC ratio must stand above 0 to be kept
BLOCK = 4096  # samples per level block (0.2 s at 20 kHz): drift is much slower
MIN_COUNT = 32  # samples a level needs in a block to be trusted there
THR_MIN, THR_MAX = 0.06, 0.45  # bounds of the threshold on z, fraction of the gap
GLITCH_K = 6.0  # noise multiples of the glitch rules
MIN_SEPARATION = 10.0  # level gap / noise below which there are no two levels
PRIOR_SAMPLES = 2_000_000  # samples used to learn the typical short-contact duration
PIECE = 1 << 20  # samples per piece of a parallel pass (pieces are claimed dynamically)
MAX_PIECES_PER_THREAD = 4  # more pieces balance the load, each costs a warm-up
EDGE_WARMUP = 256  # samples the edge pass runs before a piece to settle its state
ORPHAN_SHARE = 0.25  # a level jump: more than this share of a block's samples near
ORPHAN_SPREAD = 0.1  # ... neither tracked level, gathered within this share of the gap,
ORPHAN_BLOCKS = 2  # ... in this many consecutive blocks
ORPHAN_MIN_POINTS = 8  # strided samples a block needs to be judged (a short last block)
MAX_LEVEL_JUMPS = 8  # splits at most per recording side
TRACKED_JUMP = 0.15  # ... or a tracked level that moves this share of the gap in a block
JUMP_POINTS = 100_000  # strided samples read for level jumps
HELD_WINDOW = 0.05  # share of the gap around a level whose samples show it held (a step's check)
HELD_RATIO = 2.0  # ... and how many times the other level's (and the midpoint's) they outnumber
HELD_MIN = 8  # samples near either level or the midpoint below which a step is not judged


class NoContactsError(BouncelabError):
    """The continuity channel shows no transitions ("no contacts found")."""


@dataclass(frozen=True)
class Detection:
    """Edges found in one continuity channel.

    Times are in samples (sample ``k`` at ``t = k``), sub-sample, sorted.

    Attributes
    ----------
    t_edge : (m,) float, edge times, samples.
    kind : (m,) int8, +1 landing (open -> contact), -1 takeoff; kinds alternate.
    first_state : int, 1 when the recording starts in contact.
    contact_high : bool, True when the contact level is the higher voltage.
    open_v, contact_v : (n_blocks,) float, levels at block centres, volts.
    noise_v : (n_blocks,) float, noise standard deviation per block, volts.
    q : float, RC decay per sample; tau_samples = -1/ln q (0 when q = 0).
    d_prior : float, typical short-contact duration used for one-interval contacts, samples.
    n_glitch : (n_blocks,) int, single-sample glitches removed per block.
    n_contact : (n_blocks,) int, samples in contact per block.
    glitch_at : (g,) int, sample indices of the (first 4096) glitches removed.
    block : int, samples per block.
    n_samples : int.
    interference_v : (n_blocks,) float, rms of the fast interference (mains hum)
        subtracted before detection, volts (:mod:`.interference`); zeros when none was
        found or no sampling rate was given.
    ringing : robust size of the channel's moves before its edges, fraction of the gap,
        where it was taken as noise (:func:`pre_edge_ringing`: a filter that rings
        before each edge, as a sound card's anti-alias filter does); 0 otherwise.
    """

    t_edge: np.ndarray
    kind: np.ndarray
    first_state: int
    contact_high: bool
    open_v: np.ndarray
    contact_v: np.ndarray
    noise_v: np.ndarray
    q: float
    d_prior: float
    n_glitch: np.ndarray
    n_contact: np.ndarray
    glitch_at: np.ndarray
    block: int
    n_samples: int
    interference_v: np.ndarray = field(default_factory=lambda: np.zeros(0))
    ringing: float = 0.0

    @property
    def tau_samples(self) -> float:
        """RC time constant in samples (0 when no RC smoothing was measurable)."""
        return float(-1.0 / np.log(self.q)) if self.q > 0 else 0.0

    def flights(self) -> tuple[np.ndarray, np.ndarray]:
        """Takeoff and landing times (samples) of every complete flight, shapes (f,)."""
        take = np.flatnonzero(self.kind[:-1] == kernels.TAKEOFF)
        take = take[self.kind[take + 1] == kernels.LANDING]
        return self.t_edge[take], self.t_edge[take + 1]

    def contacts(self) -> tuple[np.ndarray, np.ndarray]:
        """Start and end (samples) of every complete contact, shapes (c,)."""
        land = np.flatnonzero(self.kind[:-1] == kernels.LANDING)
        land = land[self.kind[land + 1] == kernels.TAKEOFF]
        return self.t_edge[land], self.t_edge[land + 1]


def two_means(x: np.ndarray, max_points: int = 500_000, iters: int = 30) -> tuple:
    """Global two-cluster levels of ``x`` (volts): ``(lo, hi, sd)`` from a strided subset.

    Starts at the 0.5th and 99.5th percentiles (robust to glitches) and iterates
    two-means; ``sd`` is the pooled standard deviation of the two clusters.
    """
    step = max(1, x.shape[0] // max_points)
    s = np.asarray(x[::step], dtype=np.float64)
    lo, hi = np.percentile(s, [0.5, 99.5])
    for _ in range(iters):
        mid = 0.5 * (lo + hi)
        below = s <= mid
        if below.all() or not below.any():
            break
        new = s[below].mean(), s[~below].mean()
        if np.allclose(new, (lo, hi), rtol=0, atol=1e-12):
            break
        lo, hi = new
    mid = 0.5 * (lo + hi)
    below = s <= mid
    resid = np.where(below, s - lo, s - hi)
    return float(lo), float(hi), float(np.std(resid))


def _robust_noise(x: np.ndarray, max_points: int = 500_000) -> float:
    """Noise standard deviation (volts) from the median absolute first difference."""
    step = max(1, x.shape[0] // max_points)
    d = np.diff(np.asarray(x[: step * max_points : step], dtype=np.float64))
    return float(np.median(np.abs(d - np.median(d))) * 1.4826 / np.sqrt(2.0))


def check_transitions(x: np.ndarray, path=None, extremes=None) -> None:
    """Raise :class:`BouncelabError` when ``x`` is stuck at one value (in every sample, or
    in >= 99 % of them).

    ``extremes``: optional ``(block_min, block_max, block)`` per-block extremes (from the
    levels pass) that spare the full passes: a value can occur only in the blocks whose
    extreme it is, so it is counted only when those blocks hold >= 99 % of the samples.
    """
    n = x.shape[0]
    if extremes is None:
        xmin, xmax = float(np.min(x)), float(np.max(x))
        size_min = size_max = n
    else:
        bmin, bmax, block = extremes
        xmin, xmax = float(np.min(bmin)), float(np.max(bmax))
        sizes = np.minimum(block, n - np.arange(bmin.shape[0]) * block)
        size_min, size_max = int(sizes[bmin == xmin].sum()), int(sizes[bmax == xmax].sum())
    if xmax == xmin:
        raise BouncelabError(
            path, f"continuity channel is stuck at one rail ({xmin:.6g} V in every sample)"
        )
    # counts that cannot reach 99 % stay 0: they change neither the test nor the message
    n_min = np.count_nonzero(x == xmin) if size_min >= 0.99 * n else 0
    n_max = np.count_nonzero(x == xmax) if size_max >= 0.99 * n else 0
    n_at = max(n_min, n_max)
    if n_at >= 0.99 * n:
        rail = xmin if n_min >= n_max else xmax
        raise BouncelabError(
            path,
            f"continuity channel is stuck at one rail ({rail:.6g} V in "
            f"{100.0 * n_at / n:.1f} % of the samples)",
        )


def _fill_levels(lo_b, hi_b, lo0, hi0):
    """Fill levels missing in some blocks: other level +- the interpolated gap (volts)."""
    nb = lo_b.shape[0]
    idx = np.arange(nb)
    both = np.isfinite(lo_b) & np.isfinite(hi_b)
    if both.any():
        gap = np.interp(idx, idx[both], (hi_b - lo_b)[both])
    else:
        gap = np.full(nb, hi0 - lo0)
    lo = np.where(np.isfinite(lo_b), lo_b, hi_b - gap)
    hi = np.where(np.isfinite(hi_b), hi_b, lo_b + gap)
    for arr in (lo, hi):
        ok = np.isfinite(arr)
        if not ok.any():
            arr[:] = lo0 if arr is lo else hi0
        elif not ok.all():
            arr[:] = np.interp(idx, idx[ok], arr[ok])
    return lo, hi


def _majority_high(frac_hi: np.ndarray, block: int, intervals) -> float | None:
    """Fraction of time above the mid level inside sample ``intervals`` (None if empty)."""
    w_sum = 0.0
    f_sum = 0.0
    for a, b in intervals:
        a_blk, b_blk = int(a) // block, int(np.ceil(b / block))
        for j in range(max(a_blk, 0), min(b_blk, frac_hi.shape[0])):
            lo = max(a, j * block)
            hi = min(b, (j + 1) * block)
            if hi > lo:
                w_sum += hi - lo
                f_sum += (hi - lo) * frac_hi[j]
    return f_sum / w_sum if w_sum > 0 else None


def decide_polarity(
    frac_hi: np.ndarray,
    block: int,
    contact_level: str = "auto",
    rest_intervals=(),
    open_intervals=(),
) -> bool:
    """True when the contact level is the high one; the rules are in the module docstring.

    ``frac_hi`` (n_blocks,) is the fraction of each block above the mid level;
    ``rest_intervals`` / ``open_intervals`` are (start, end) sample ranges where the body
    is known to rest on the plate / to be off it.
    """
    if contact_level == "high":
        return True
    if contact_level == "low":
        return False
    f = _majority_high(frac_hi, block, rest_intervals)
    if f is not None and abs(f - 0.5) > 0.05:
        return f > 0.5
    f = _majority_high(frac_hi, block, open_intervals)
    if f is not None and abs(f - 0.5) > 0.05:
        return f < 0.5
    return float(np.mean(frac_hi)) < 0.5


#: Edges a channel needs before :func:`point_sampled` judges it, and the largest share
#: of them with a sample between the levels that a point-sampled channel shows.
POINT_MIN_EDGES, POINT_MAX_SHARE = 50, 0.05


def point_sampled(t_edge: np.ndarray) -> bool:
    """Whether a channel read with the box model (no RC) was sampled at instants rather
    than averaged over each interval: hardly any edge has a sample between the levels.

    ``t_edge`` (n,) edge times in samples, as the box model places them: ``k - z`` for a
    rise inside ``(k-1, k]`` whose sample ``k`` holds the contact fraction ``z``, and its
    mirror for a fall. An averaging front end gives ``z`` spread over (0, 1), so most
    edges fall inside an interval; a data-acquisition card that holds one instant per
    sample, on a circuit faster than its sampling (a clean TTL level), gives only
    ``z`` 0 or 1, every edge on a sample, half a sample early on average: the edge lies
    anywhere in the interval, and its middle is the unbiased place. A black-box probe's
    clean TTL recordings had takeoffs 22 us and landings 28 us early at 20 kHz (drive
    phases 0.004 rad early; flight times unbiased).
    """
    if t_edge.size < POINT_MIN_EDGES:
        return False
    frac = t_edge - np.floor(t_edge)
    inside = (frac > 0.1) & (frac < 0.9)
    return bool(np.mean(inside) < POINT_MAX_SHARE)


def estimate_q(
    x, block, open_b, gap_b, max_ratios: int = 200_000, par=None, unmeasured: float = 0.0
) -> float:
    """RC decay per sample from clean edges (median ratio); ``unmeasured`` (0: the box
    model) when fewer than 8 edges are clean.

    ``par``: a :class:`Parallel` to scan pieces at once (the ratios, concatenated in
    order, are the serial kernel's)."""
    par = par or Parallel(1)
    r, slow = _rc_ratios(x, block, open_b, 1.0 / gap_b, max_ratios, par)
    if r.size < 8:
        # no edge settles within 0.1 of its level two samples on: a front end slower
        # than the sampling (tau over about 1.5 samples), read where the decay holds
        # one ratio; before, q came out 0 and the box model read every RC tail as edges
        r = np.concatenate([r, slow])
        # one RC gives one ratio (a MAD of 0.001 on the rig through 100-250 us); ratios
        # spread wider are windows of noise that happened to fall
        if r.size >= 8 and np.median(np.abs(r - np.median(r))) > SLOW_MAD_MAX:
            return unmeasured
    if r.size < 8:
        return unmeasured
    q = float(np.median(r))
    # a median the ratios' noise does not resolve from 0 is a box front end read through
    # noise (a probe's 0.3 V level gap: tau "7 us", and the RC placement moved edges by
    # up to half a sample); standard error of the median from the ratios' MAD
    se = 1.2533 * 1.4826 * float(np.median(np.abs(r - q))) / np.sqrt(r.size)
    return 0.0 if q < max(kernels.Q_MIN, Q_RESOLVED * se) else min(q, 0.9)


#: RC decay per sample (tau over 0.8 samples) from which the tails of the edges,
#: within a quarter gap of a level for several samples, inflate the block noise that the
#: threshold is set from; there the threshold's noise is capped at ``SLOW_SDZ_CAP``
#: times the deconvolved channel's own (:func:`deconvolved_noise`).
SLOW_Q, SLOW_SDZ_CAP = 0.3, 2.5


#: Samples before an edge's interval where a causal front end is still at its level
#: (``RING_LAGS``), and those its local level is read from (``RING_LEVEL_LAGS``); edges
#: with another edge nearer than the farthest of them are not read. A ringing whose
#: robust size exceeds ``RING_NOISE`` times the channel's sample noise, on
#: ``RING_MIN_EDGES`` edges or more, is treated as noise (:func:`pre_edge_ringing`).
RING_LAGS = (2, 3, 4)
RING_LEVEL_LAGS = tuple(range(5, 13))
RING_NOISE, RING_MIN_EDGES, RING_MAX_EDGES = 5.0, 50, 4096
#: ... and at least this share of the gap: a channel without noise (clipped flat at a
#: sound card's full scale) read 1.5e-15 as ringing, above 5 x its zero noise
RING_FLOOR = 1e-3


def _line_weights(src, dst) -> np.ndarray:
    """(len(src), len(dst)) weights that carry samples at lags ``src`` to lags ``dst``
    along their least-squares straight line."""
    design = np.column_stack([np.ones(len(src)), np.asarray(src, float)])
    return np.linalg.pinv(design).T @ np.vstack([np.ones(len(dst)), np.asarray(dst, float)])


_RING_LINE = _line_weights(RING_LEVEL_LAGS, RING_LAGS)


def pre_edge_ringing(x, t_edge, block, gap_b) -> tuple[float, int]:
    """Robust size (fraction of the gap) of the channel's moves just before its edges.

    A front end that is causal (a wire, an RC, a DAQ's sample-and-hold) holds its level
    until the edge's own sample interval, so the samples 2-4 before it lie on the line
    of the samples 5-12 before it, up to the noise. A sound card's linear-phase
    anti-alias filter rings before each edge as after it (its Gibbs lobes, a few % of
    the gap), and at a short contact those lobes and the contact's own smeared sample
    crossed a threshold set from the quiet noise: a virtual-rig recording through such a
    filter (44.1 kHz, 127 taps) read 6-21 flights of 5-23 us inside contacts and lost 1-2
    real ones. The lobes are read here so that the detection can take them as noise.

    Parameters
    ----------
    x : (n,) float, the continuity channel, V.
    t_edge : (m,) float, edge times of a first detection, samples.
    block : samples per level block; gap_b : (nb,) contact minus open level per block, V.

    Returns
    -------
    (ring, n_edges) : 1.4826 x the median absolute deviation, fraction of the gap, of the
        samples at :data:`RING_LAGS` before each isolated edge from the straight line
        through those at :data:`RING_LEVEL_LAGS`; NaN and 0 with no isolated edge.
    """
    far = max(RING_LEVEL_LAGS)
    k = np.ceil(t_edge).astype(np.int64)  # the edge lies in (k - 1, k]
    prev = np.concatenate([[-np.inf], t_edge[:-1]])
    keep = (t_edge - prev > far + 1) & (k - far >= 0) & (k < x.shape[0])
    k = k[keep]
    if k.size == 0:
        return float("nan"), 0
    k = k[:: -(-k.size // RING_MAX_EDGES)]  # spread over the recording; a median needs few
    # the level is a straight line through the farther samples, carried to the nearer
    # ones: a hum moves the channel by about its slope times the 5-sample lag, which a
    # flat level read as ringing (6.7 x the noise under a 50 Hz hum of 5 % of the gap)
    level = x[k[:, None] - np.array(RING_LEVEL_LAGS)] @ _RING_LINE
    near = x[k[:, None] - np.array(RING_LAGS)] - level
    gap = np.abs(gap_b[np.minimum(k // block, gap_b.shape[0] - 1)])
    dev = np.abs(near) / gap[:, None]
    return float(1.4826 * np.median(dev)), int(k.size)


HELD_BAND = (0.1, 0.9)  # share of the gap a held level lies in (edges pass through)
HELD_MIN_S = 1e-3  # shortest stretch between the levels reported as held, seconds
HELD_TAU = 8.0  # ... and in RC time constants (an edge's tail crosses the band in < 2)
HELD_SPREAD = 0.05  # largest standard deviation (share of the gap; or 3 noise sigmas) of
# a held stretch: a level, not a hum's or a drift's passage through the band


@dataclass(frozen=True)
class HeldStretches:
    """Stretches where the continuity channel sits between its levels.

    count : int, stretches of at least ``min_samples`` samples in :data:`HELD_BAND`.
    samples : int, their samples in all.
    longest_start, longest_len : int, first sample and length (samples) of the longest.
    """

    count: int
    samples: int
    longest_start: int
    longest_len: int


def interference_removed(x: np.ndarray, sample_rate_hz: float, block: int = BLOCK) -> np.ndarray:
    """The channel (n,) volts with its fast interference (mains hum) subtracted as the
    detection subtracts it (:func:`remove_interference`, same levels and noise), or
    ``x`` itself where none is found."""
    s = _subsample(x)
    lo0, hi0, _ = two_means(s)
    if not sample_rate_hz or not hi0 > lo0:
        return x
    return remove_interference(x, lo0, hi0, _robust_noise(s), sample_rate_hz, block)[0]


def held_stretches(
    x: np.ndarray, det: Detection, min_samples: int, chunk: int = 1 << 20
) -> HeldStretches:
    """Stretches of the channel held between the levels (a contact that half-conducts).

    Parameters
    ----------
    x : (n,) samples, volts, as the edge pass read them (:func:`interference_removed`).
    det : the :class:`Detection` of ``x`` (its block levels).
    min_samples : shortest stretch counted, samples.
    chunk : samples per pass (memory: a few float64 arrays of that size).

    A stretch counts when it is also flat: its standard deviation at most
    :data:`HELD_SPREAD` of the gap or 3 sigmas of its white noise (a mains hum of 20 % of the gap
    keeps the open level in the band for half its cycles; a probe's such hum gave 2084
    stretches before).  The edge pass reads such a level as one contact where it lies
    above the detection threshold (:func:`kernels._held_reading`); this only measures
    it, for a warning.
    """
    n = x.shape[0]
    centre = (np.arange(det.open_v.shape[0]) + 0.5) * det.block
    gap = det.contact_v - det.open_v
    inside = np.empty(n, dtype=bool)
    for a in range(0, n, chunk):
        k = np.arange(a, min(a + chunk, n))
        u = (x[k] - np.interp(k, centre, det.open_v)) / np.interp(k, centre, gap)
        inside[k] = (u > HELD_BAND[0]) & (u < HELD_BAND[1])
    change = np.flatnonzero(np.diff(np.concatenate(([False], inside, [False])).view(np.int8)))
    starts, ends = change[::2], change[1::2]
    length = ends - starts
    keep = length >= max(int(min_samples), 1)
    for i in np.flatnonzero(keep):
        k = np.arange(starts[i], ends[i])
        u = (x[k] - np.interp(k, centre, det.open_v)) / np.interp(k, centre, gap)
        # white noise from the first differences: blind to a slow hum or drift
        sigma = 1.4826 * float(np.median(np.abs(np.diff(u)))) / np.sqrt(2.0)
        keep[i] = float(np.std(u)) <= max(HELD_SPREAD, 3.0 * sigma)
    if not keep.any():
        return HeldStretches(0, 0, 0, 0)
    i = int(np.argmax(np.where(keep, length, -1)))
    return HeldStretches(int(keep.sum()), int(length[keep].sum()), int(starts[i]), int(length[i]))


def deconvolved_noise(x, block, open_b, gap_b, q, chunks: int = 64, length: int = 4096):
    """Robust standard deviation of the deconvolved contact fraction ``z`` (fraction of
    the gap), read on ``chunks`` stretches of ``length`` samples spread over ``x``.

    ``z[k] = (u[k] - q u[k-1]) / (1 - q)`` is 0 or 1 plus white noise away from edges
    and an impulse at each edge; edges are a small minority of the samples, so
    1.4826 x the median absolute deviation of ``z`` from its nearer level is the noise,
    where the block levels' standard deviation also counts the RC tails (on a 100 us
    front end at 20 kHz: 6.5 times the noise, and the 6-sigma threshold missed short
    contacts).
    """
    n = x.shape[0]
    starts = np.linspace(0, max(n - length, 0), chunks).astype(np.int64)
    centre = (np.arange(open_b.shape[0]) + 0.5) * block
    dev = []
    for a in np.unique(starts):
        k = np.arange(a, min(a + length, n))
        u = (x[k] - np.interp(k, centre, open_b)) / np.interp(k, centre, gap_b)
        z = (u[1:] - q * u[:-1]) / (1.0 - q)
        dev.append(np.minimum(np.abs(z), np.abs(z - 1.0)))
    d = np.concatenate(dev) if dev else np.zeros(1)
    return float(1.4826 * np.median(d))


def _rc_ratios(x, block, open_b, inv, max_ratios, par) -> tuple[np.ndarray, np.ndarray]:
    """Finite RC ratios of :func:`kernels.rc_range`, ``(strict, slow)``: a prefix usually
    holds enough clean edges, the whole recording is read only if it does not."""
    n = x.shape[0]
    head = min(n, PRIOR_SAMPLES)
    r, slow = par.rc_ratios(x, 0, head, block, open_b, inv, max_ratios)
    if r.size < 200 and n > PRIOR_SAMPLES:
        rest, rest_slow = par.rc_ratios(x, PRIOR_SAMPLES, n, block, open_b, inv, max_ratios)
        r = np.concatenate([r, rest])[:max_ratios]
        slow = np.concatenate([slow, rest_slow])[:max_ratios]
    return r[np.isfinite(r)], slow[np.isfinite(slow)]


def _short_contact_prior(t_edge, kind, max_len=1.0) -> float:
    """Typical duration (samples) of contacts shorter than ``max_len`` samples; 0 if
    fewer than 20 were timed.

    Only contacts whose two edges fall in different sample intervals (each edge timed
    from its own sample) are used.  A contact of duration d straddles a sample instant
    with probability ~d, so the weighted median with weights 1/d undoes that length bias.
    """
    land = np.flatnonzero(kind[:-1] == kernels.LANDING)
    land = land[kind[land + 1] == kernels.TAKEOFF]
    ta, tb = t_edge[land], t_edge[land + 1]
    d = tb - ta
    ok = (d > 0) & (d < max_len) & (np.ceil(ta) < np.ceil(tb))
    if np.count_nonzero(ok) < 20:
        return 0.0
    d = np.sort(d[ok])
    w = np.cumsum(1.0 / d)
    return float(d[np.searchsorted(w, 0.5 * w[-1])])


class Parallel:
    """Runs the kernels' pieces on ``n_threads`` threads and stitches them.

    ``piece`` is the length of a piece in samples (None: about :data:`PIECE`, at least
    two per thread and at most :data:`MAX_PIECES_PER_THREAD`); tests set it small so that
    cuts fall everywhere.  Used as a context manager (the thread pool lives inside).
    """

    def __init__(self, n_threads: int | None = None, piece: int | None = None):
        self.n_threads = max(1, int(n_threads or numba.get_num_threads()))
        self.piece = piece
        self.reruns = 0  # edge pieces rerun because their warm-up did not settle
        self._pool = None

    def __enter__(self):
        if self.n_threads > 1:
            self._pool = ThreadPoolExecutor(self.n_threads)
        return self

    def __exit__(self, *exc):
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None

    def map(self, fn, arg_tuples):
        """``[fn(*a) for a in arg_tuples]``, on the pool when there is one."""
        if self._pool is None or len(arg_tuples) < 2:
            return [fn(*a) for a in arg_tuples]
        return list(self._pool.map(lambda a: fn(*a), arg_tuples))

    def submit(self, fn, *args):
        """A future of ``fn(*args)`` (run at once without a pool)."""
        if self._pool is None:
            return _Done(fn(*args))
        return self._pool.submit(fn, *args)

    def bounds(self, lo: int, hi: int, unit: int = 1, cuts=()) -> np.ndarray:
        """Increasing bounds of pieces covering ``[lo, hi)``, in steps of ``unit``
        samples (a block), with the extra cut points ``cuts`` inside."""
        span = max(hi - lo, 0)
        if self.piece:
            count = -(-span * unit // max(self.piece, 1))
        else:
            count = min(-(-span * unit // PIECE), MAX_PIECES_PER_THREAD * self.n_threads)
            count = max(count, 2 * self.n_threads) if self.n_threads > 1 else 1
        count = int(max(1, min(count, span)))
        b = lo + (np.arange(count + 1) * span) // count
        extra = [c for c in cuts if lo < c < hi]
        return np.unique(np.concatenate([b, np.asarray(extra, dtype=b.dtype)]))

    def rc_ratios(self, x, k_lo, k_hi, block, open_b, inv_b, max_out):
        """:func:`kernels.rc_range` over ``[k_lo, k_hi)`` in pieces: the serial ratios,
        ``(strict, slow)``."""
        pieces = _pairs(self.bounds(k_lo, k_hi))
        args = [(x, a, e, block, open_b, inv_b, max_out) for a, e in pieces]
        parts = self.map(kernels.rc_range, args)
        if not parts:
            return np.empty(0), np.empty(0)
        return tuple(np.concatenate([p[i] for p in parts])[:max_out] for i in (0, 1))

    def block_levels(self, x, block, lo0, hi0, min_count):
        """:func:`kernels.block_levels_serial` in runs of blocks (bit for bit), and the
        records (with the per-block extremes)."""
        rec = kernels.new_level_records(x.shape[0], block)
        runs = _pairs(self.bounds(0, rec.shape[0], unit=block))
        args = [(x, block, lo0, hi0, min_count, a, e, rec) for a, e in runs]
        self.map(kernels.levels_run, args)
        return kernels.levels_walk(x, block, lo0, hi0, min_count, rec), rec

    def edges(self, x, params, cuts=()):
        """The edge pass :func:`kernels.detect_edges_serial` with ``d_prior = 0`` over the
        whole recording, in pieces, stitched: returns the list of pieces' results
        (:func:`kernels.edge_range` tuples), their bounds and the true state each
        started from.

        A piece after the first runs :data:`EDGE_WARMUP` samples before its own from a
        guessed state; when the state it reaches differs from the one the previous piece
        really ended in, it is rerun from the true state.
        """
        n = x.shape[0]
        pieces = _pairs(self.bounds(1, n, cuts=cuts))
        runs = self.map(_edge_piece, [(x, a, e, params) for a, e in pieces])
        results, starts = [], []
        state, u = runs[0][0], runs[0][1]  # the first piece starts as the serial pass
        for (a, e), (s0, u0, res) in zip(pieces, runs, strict=True):
            if s0 != state or u0 != u:
                res = kernels.edge_range(x, a, e, state, u, *params)
                self.reruns += 1
            starts.append((state, u))
            results.append(res)
            state, u = int(res[5]), float(res[6])
        return results, pieces, starts


def _pairs(bounds) -> list[tuple[int, int]]:
    """Consecutive ``(start, end)`` pairs of increasing bounds."""
    b = [int(v) for v in bounds]
    return list(zip(b[:-1], b[1:], strict=True))


class _Done:
    """A finished "future" (no pool)."""

    def __init__(self, value):
        self.value = value

    def result(self):
        return self.value


def _edge_piece(x, a, e, params):
    """Edges of the iterations ``[a, e)``, started from the serial state when ``a == 1``
    else from the state reached after a warm-up from a guess; returns
    ``(start_state, start_u_prev, result)``."""
    block, open_b, inv_b = params[0], params[1], params[2]
    w0 = max(1, a - EDGE_WARMUP)
    u_g = float(kernels.u_at(x, w0 - 1, block, open_b, inv_b))
    state = 1 if u_g > 0.5 else 0  # the serial pass's own start when w0 == 1
    if w0 < a:
        warm = kernels.edge_range(x, w0, a, state, u_g, *params)
        state, u_g = int(warm[5]), float(warm[6])
    return state, u_g, kernels.edge_range(x, a, e, state, u_g, *params)


def _high_share(x: np.ndarray) -> float:
    """Share of ``x``'s (strided) samples above the mid level of its two means."""
    s = _subsample(x)
    lo, hi, _ = two_means(s)
    return float(np.mean(s > 0.5 * (lo + hi)))


def _subsample(x: np.ndarray, max_points: int = 500_000) -> np.ndarray:
    """``x[::step]`` in float64 with ``step = max(1, n // max_points)``: the points that
    :func:`two_means` and :func:`_robust_noise` use (they pick the same ones from it)."""
    step = max(1, x.shape[0] // max_points)
    return np.asarray(x[::step], dtype=np.float64)


def detect_contacts(
    x: np.ndarray,
    contact_level: str = "auto",
    rest_intervals=(),
    open_intervals=(),
    block: int = BLOCK,
    path=None,
    n_threads: int | None = None,
    piece: int | None = None,
    sample_rate_hz: float | None = None,
) -> Detection:
    """Find every contact and flight edge in a continuity channel.

    Parameters
    ----------
    x : (n,) float array, the continuity channel in volts (any offset, either polarity).
    contact_level : ``"auto"``, ``"low"`` or ``"high"``.
    rest_intervals, open_intervals : iterables of (start, end) sample indices where the
        body is known to rest on the plate / to be off it (polarity hints for ``auto``).
    block : samples per level block.
    path : file named in errors.
    n_threads : threads for the passes over the samples (None: numba's thread count).
    piece : samples per piece of a parallel pass (None: automatic).  Neither changes
        the result, which is bit for bit that of the serial kernels.
    sample_rate_hz : sampling rate; with it a fast interference (mains hum) is found
        and, where clearly there, subtracted first (:mod:`.interference`).  None: not
        looked for.

    Raises
    ------
    BouncelabError
        The channel is stuck at one rail, or shows no transitions ("no contacts found").
    """
    x = np.ascontiguousarray(x)
    if x.shape[0] < 3:
        raise BouncelabError(path, "continuity channel has fewer than 3 samples")
    with Parallel(n_threads, piece) as par:
        det = _detect_split(
            x, contact_level, rest_intervals, open_intervals, block, path, par, sample_rate_hz
        )
    return _in_order(det)


def _in_order(det: Detection) -> Detection:
    """``det`` with every flight or contact of no positive length removed, so the edge
    times rise strictly: its two edges go, and the contacts (flights) around it merge.

    Each edge of a one-interval pulse is placed from that interval's sample alone, so on
    a front end that rings (a sound card's linear-phase anti-alias filter behind an
    AC coupling) a chatter burst could give a landing 14 us before its takeoff: a
    flight of negative length in the table.  The same object when all is in order."""
    t, kind = det.t_edge, det.kind
    if t.shape[0] < 2 or bool(np.all(np.diff(t) > 0)):
        return det
    keep = np.ones(t.shape[0], dtype=bool)
    while True:
        idx = np.flatnonzero(keep)
        bad = np.flatnonzero(np.diff(t[idx]) <= 0)
        if bad.size == 0:
            break
        # one pair at a time from the left of each run: removing (i, i+1) may put i-1
        # and i+2 out of order, which the next round sees
        first = bad[np.concatenate(([True], np.diff(bad) > 1))]
        keep[idx[first]] = False
        keep[idx[first + 1]] = False
    return replace(det, t_edge=t[keep], kind=kind[keep])


#: A switch's contact bounce: openings shorter than ``BOUNCE_MAX`` of a sample interval
#: that start within ``BOUNCE_WINDOW_S`` of the landing that ended a flight at least
#: ``BOUNCE_RATIO`` times longer (:func:`without_switch_bounce`).
BOUNCE_MAX, BOUNCE_WINDOW_S, BOUNCE_RATIO = 0.9, 1e-4, 100.0


def without_switch_bounce(det: Detection, fs: float) -> tuple[Detection, int]:
    """``det`` without the openings of a switch's contact bounce, and their count.

    A mechanical contact that closes may open again for microseconds, two to four times
    within 0.1 ms (a black-box probe's 3-15 us openings: 1572 flights for 825, none
    warned of). Such an opening is shorter than a sample (``BOUNCE_MAX``) and follows,
    within ``BOUNCE_WINDOW_S``, the landing of a flight at least ``BOUNCE_RATIO`` times
    longer (the last flight of at least ``BOUNCE_MAX``). A body's rebound is not that
    much shorter than the flight before it unless its restitution is below 0.01, and
    then below what the sampling resolves anyway. Its two edges go and the contacts
    around it merge. ``fs``: sampling rate, Hz (the window is in seconds). On the
    shipped runs and the 80 independent and compliant recordings: none.
    """
    t, kind = det.t_edge, det.kind
    take = np.flatnonzero(kind[:-1] == kernels.TAKEOFF)
    take = take[kind[take + 1] == kernels.LANDING]
    if take.size == 0:
        return det, 0
    length = t[take + 1] - t[take]
    short = length < BOUNCE_MAX
    if not short.any():
        return det, 0
    # the last flight of at least BOUNCE_MAX at or before each flight (-1: none)
    ref = np.maximum.accumulate(np.where(short, -1, np.arange(take.size)))
    has_ref = ref >= 0
    ref_c = np.maximum(ref, 0)
    bounce = (
        short
        & has_ref
        & (t[take] - t[take[ref_c] + 1] <= BOUNCE_WINDOW_S * fs)
        & (length[ref_c] >= BOUNCE_RATIO * length)
    )
    if not bounce.any():
        return det, 0
    keep = np.ones(t.shape[0], dtype=bool)
    keep[take[bounce]] = False
    keep[take[bounce] + 1] = False
    return replace(det, t_edge=t[keep], kind=kind[keep]), int(bounce.sum())


def _detect_split(
    x,
    contact_level,
    rest_intervals,
    open_intervals,
    block,
    path,
    par,
    sample_rate_hz,
    depth=0,
    q_unmeasured=0.0,
) -> Detection:
    """:func:`_detect`, and where the levels jumped (:func:`level_jump`: a gain or supply
    change) each side again on its own, with the polarity found on the whole and, where a
    side holds too few clean edges to measure it, the whole's RC constant (a gain or
    offset step leaves the front end as it was: a side of bouncing alone, with no rests,
    was read with the box model, its flight times 9 us off for 0.8)."""
    det = _detect(
        x,
        contact_level,
        rest_intervals,
        open_intervals,
        block,
        path,
        par,
        sample_rate_hz,
        q_unmeasured,
    )
    cut = level_jump(x, det) if depth < MAX_LEVEL_JUMPS else None
    if cut is None:
        return det
    cut = refine_cut(x, cut, block)
    if not block <= cut <= x.shape[0] - block:
        return det  # at an end: nothing to split off
    high = det.contact_high
    if contact_level == "auto" and not len(rest_intervals) and not len(open_intervals):
        # rule (3) read on the whole mixes the sides' levels (a gain drop to near the old
        # mid level reads the new open level as contact): read it on each side instead
        high = _high_share(x[:cut]) * cut + _high_share(x[cut:]) * (x.shape[0] - cut) < (
            0.5 * x.shape[0]
        )
    level = "high" if high else "low"
    parts = []
    for a, b in ((0, cut), (cut, x.shape[0])):
        try:
            side = _detect_split(
                x[a:b], level, (), (), block, path, par, sample_rate_hz, depth + 1, det.q
            )
        except NoContactsError:
            side = None  # e.g. a side where the body rests all along
        parts.append((a, side))
    return det if all(d is None for _, d in parts) else _joined(parts, det, block, high)


def level_jump(x: np.ndarray, det: Detection) -> int | None:
    """A block boundary near the first jump of the levels (a gain or supply change), or
    None.

    The block levels follow drift of less than a quarter of the gap per block.  A level
    that moves further at once is either lost (its samples then lie near neither tracked
    level: "orphans"; transition samples are orphans too, but spread between the levels,
    while a lost level gathers them at one value) or followed, but blurred over a block
    by the interpolation between block centres.  Found as ``ORPHAN_BLOCKS`` consecutive
    blocks with more than ``ORPHAN_SHARE`` of the (strided) samples orphaned within
    ``ORPHAN_SPREAD`` of the gap of each other, or a tracked level that moves more than
    ``TRACKED_JUMP`` of the gap from one block to the next.  An orphan run that ends
    before the recording does marks the jump at its end (the levels were wrong before
    it: the start's levels mixed both sides'); one that lasts to the end, at its start
    (the tracking lost a level there).  The earliest candidate is returned;
    :func:`refine_cut` finds the sample.
    """
    n = x.shape[0]
    step = max(1, n // JUMP_POINTS)
    idx = np.arange(0, n, step)
    v = np.asarray(x[::step], dtype=np.float64)
    blk = idx // det.block
    nb = det.open_v.shape[0]
    lo, hi = det.open_v[blk], det.contact_v[blk]
    gap = np.abs(hi - lo)
    orphan = (np.abs(v - lo) > 0.25 * gap) & (np.abs(v - hi) > 0.25 * gap)
    cnt = np.bincount(blk, minlength=nb).astype(np.float64)
    k = np.bincount(blk, weights=orphan.astype(np.float64), minlength=nb)
    s1 = np.bincount(blk, weights=np.where(orphan, v, 0.0), minlength=nb)
    s2 = np.bincount(blk, weights=np.where(orphan, v * v, 0.0), minlength=nb)
    g = np.abs(det.contact_v - det.open_v)
    with np.errstate(invalid="ignore", divide="ignore"):
        spread = np.sqrt(np.maximum(s2 / k - (s1 / k) ** 2, 0.0))
        bad = (k > ORPHAN_SHARE * cnt) & (k >= ORPHAN_MIN_POINTS) & (spread < ORPHAN_SPREAD * g)
    # runs of bad blocks: [starts[i], ends[i])
    edges = np.diff(np.concatenate(([0], bad.astype(np.int8), [0])))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    long = ends - starts >= ORPHAN_BLOCKS
    cuts = []
    if long.any():
        r0, r1 = int(starts[long][0]), int(ends[long][0])
        # levels tracked right after the run, wrong during it (the start's levels were a
        # mixture of both sides'): the jump ends the run; else the tracking lost a level
        # at the jump and never found it again: the jump starts the run
        to_end = not (cnt[r1:] >= ORPHAN_MIN_POINTS).any()  # no judged block after it
        cuts.append(max(r0 - 1, 1) * det.block if to_end else r1 * det.block)
    # a jump the tracking followed: levels interpolated across it blur one block
    for j in np.flatnonzero(
        (_level_step(det.open_v) > TRACKED_JUMP * g[:-1])
        | (_level_step(det.contact_v) > TRACKED_JUMP * g[:-1])
    ):
        if any(
            _step_held(x, level, int(j), det.block, g[j]) for level in (det.open_v, det.contact_v)
        ):
            cuts.append((int(j) + 1) * det.block)
            break
    cuts = [c for c in cuts if 0 < c < n]
    return min(cuts) if cuts else None


def _step_held(
    x: np.ndarray, level: np.ndarray, j: int, block: int, gap: float, k: int = 3
) -> bool:
    """Whether the samples show ``level`` (per block, volts) stepping at the block
    boundary ``j | j+1`` by more than ``TRACKED_JUMP`` of ``gap``.

    The old level is the median of the ``k`` blocks before, the new one of the ``k``
    after, as :func:`_level_step` reads them.  In the ``k - 1`` blocks before the
    boundary the old level must be held, and in the ``k - 1`` blocks after the two the
    step blurs, the new one: within ``HELD_WINDOW`` of the gap of it lie ``HELD_RATIO``
    times as many samples as near the other level and as near the midpoint between
    them (where only samples passing from one level to the other lie).  A window with
    fewer than ``HELD_MIN`` samples near any of the three cannot refute the step.

    A level read off samples that never settle is not a level that moved.  Contacts
    shorter than a sample (a body chattering at high Gamma) fill the contact band with
    partial samples, whose banded mean wanders by a fifth of the gap from block to block
    while the samples that reach the contact sit where they were, and the partial
    samples spread evenly about the mean: blind ``ool_vibration`` was split 5 times on
    such wanderings, up or back down (11 detection passes, no real jump).
    """
    old = float(np.median(level[max(0, j - k + 1) : j + 1]))
    new = float(np.median(level[j + 1 : j + 1 + k]))
    if not abs(new - old) > TRACKED_JUMP * abs(gap):
        return False
    w = HELD_WINDOW * abs(gap)

    def held(a: int, b: int, here: float, there: float) -> bool:
        v = np.asarray(x[max(0, a) * block : max(0, b) * block], dtype=np.float64)
        n_here, n_there, n_mid = (
            int(np.count_nonzero(np.abs(v - c) < w)) for c in (here, there, 0.5 * (old + new))
        )
        if n_here + n_there + n_mid < HELD_MIN:
            return True
        return n_here >= HELD_RATIO * max(n_there, n_mid, 1)

    return held(j - k + 1, j, old, new) and held(j + 3, j + 2 + k, new, old)


def _level_step(level: np.ndarray, k: int = 3) -> np.ndarray:
    """``|median(level[j+1 : j+1+k]) - median(level[j-k+1 : j+1])|`` for each boundary
    ``j | j+1`` between blocks (the ends repeated), shape ``(n_blocks - 1,)``: a lasting
    step of a block level, not one block's noisy estimate (a level seen in few samples)."""
    if level.shape[0] < 2:
        return np.zeros(0)
    padded = np.concatenate((np.full(k - 1, level[0]), level, np.full(k - 1, level[-1])))
    med = np.median(np.lib.stride_tricks.sliding_window_view(padded, k), axis=1)
    # med[i] covers level[i-k+1 : i+1] (the ends repeated); before j+1 and after j
    return np.abs(med[k : k + level.shape[0] - 1] - med[: level.shape[0] - 1])


def refine_cut(x: np.ndarray, cut: int, block: int, passes: int = 3) -> int:
    """The sample where the levels jump, near a block boundary ``cut`` of :func:`level_jump`.

    The levels on each side come from a two-means split of the samples 1-4 blocks away
    from ``cut``; within two blocks of it, the jump is the index that best separates the
    samples that fit only the left side's levels (within a quarter of its gap, and clearly
    nearer to them than to the right side's) from those that fit only the right side's.
    ``cut`` itself when a side shows no two levels.

    :func:`level_jump` may place ``cut`` up to two blocks before the jump, so the first
    right-side window can still hold the old levels (its two means then read the old and
    the new open level, and a gain drop to near the old mid level put the cut 50 ms
    early, losing every flight after it): the levels are read again around each refined
    cut, for at most ``passes`` passes, until the cut stays put.
    """
    for _ in range(passes):
        new = _refine_cut_once(x, cut, block)
        if new == cut:
            break
        cut = new
    return cut


def _refine_cut_once(x: np.ndarray, cut: int, block: int) -> int:
    """One pass of :func:`refine_cut`: levels read 1-4 blocks either side of ``cut``."""
    n = x.shape[0]
    left = np.asarray(x[max(0, cut - 4 * block) : max(0, cut - block)], dtype=np.float64)
    right = np.asarray(x[min(n, cut + block) : min(n, cut + 4 * block)], dtype=np.float64)
    if left.shape[0] < block or right.shape[0] < block:
        return cut
    lv, rv = two_means(left)[:2], two_means(right)[:2]
    noise = max(_robust_noise(left), _robust_noise(right), 1e-12)
    if min(lv[1] - lv[0], rv[1] - rv[0]) < MIN_SEPARATION * noise:
        return cut
    a, b = max(0, cut - 2 * block), min(n, cut + 2 * block)
    w = np.asarray(x[a:b], dtype=np.float64)

    def distance(levels):
        return np.minimum(np.abs(w - levels[0]), np.abs(w - levels[1]))

    # a sample is one side's when it lies within a quarter of that side's gap of one of
    # its levels and clearly nearer to it than to either of the other side's (a shift of
    # both levels by less than half the gap leaves every sample within a quarter gap of
    # both sides' levels); a level the jump left in place (or moved by less than a tenth
    # of the gap: the tracking follows such a step) fits both, and counts for neither
    dl, dr = distance(lv), distance(rv)
    clear = max(3.0 * noise, 0.1 * min(lv[1] - lv[0], rv[1] - rv[0]))
    only_l = (dl < 0.25 * (lv[1] - lv[0])) & (dr - dl > clear)
    only_r = (dr < 0.25 * (rv[1] - rv[0])) & (dl - dr > clear)
    # misfits when cutting before sample i: right-only samples before i, left-only after
    cost = np.concatenate(([0], np.cumsum(only_r))) + (
        only_l.sum() - np.concatenate(([0], np.cumsum(only_l)))
    )
    return a + int(np.argmin(cost))


def _joined(parts, whole: Detection, block: int, contact_high: bool) -> Detection:
    """One :class:`Detection` from the detections of consecutive pieces
    ``[(start, det or None), ...]`` (None: no contacts there).  Per-block arrays are
    read on the whole recording's block grid, each block from the piece holding its
    centre (``whole``'s own where that piece has none); ``contact_high`` is the polarity
    the pieces were detected with."""
    nb = whole.open_v.shape[0]
    centre = (np.arange(nb) + 0.5) * block
    starts = np.array([a for a, _ in parts])
    which = np.searchsorted(starts, centre, side="right") - 1
    per_block = {}
    for k in _PER_BLOCK:
        base = getattr(whole, k)
        vals = np.array(base if base.shape[0] == nb else np.zeros(nb))
        for i, (a, d) in enumerate(parts):
            arr = getattr(d, k) if d is not None else np.zeros(0)
            if arr.shape[0] == 0:
                continue
            m = which == i
            local = np.clip(((centre[m] - a) // block).astype(np.int64), 0, arr.shape[0] - 1)
            vals[m] = arr[local]
        per_block[k] = vals
    found = [(a, d) for a, d in parts if d is not None]
    t_all = np.concatenate([d.t_edge + a for a, d in found])
    kind_all = np.concatenate([d.kind for _, d in found])
    keep = np.ones(kind_all.shape[0], dtype=bool)
    keep[1:] = kind_all[1:] != kind_all[:-1]  # kinds alternate across a junction too
    main = max((d for _, d in found), key=lambda d: d.n_samples)
    return Detection(
        t_edge=t_all[keep],
        kind=kind_all[keep],
        first_state=parts[0][1].first_state if parts[0][1] is not None else whole.first_state,
        contact_high=contact_high,
        q=main.q,
        d_prior=main.d_prior,
        glitch_at=np.concatenate([d.glitch_at + a for a, d in found])[:4096],
        block=block,
        n_samples=whole.n_samples,
        ringing=max(d.ringing for _, d in found),
        **per_block,
    )


_PER_BLOCK = ("open_v", "contact_v", "noise_v", "n_glitch", "n_contact", "interference_v")


def _detect(
    x,
    contact_level,
    rest_intervals,
    open_intervals,
    block,
    path,
    par,
    sample_rate_hz=None,
    q_unmeasured=0.0,
) -> Detection:
    """:func:`detect_contacts` with its pieces run by ``par`` (a :class:`Parallel`);
    ``q_unmeasured``: the RC constant taken where too few edges are clean to measure it."""
    n = x.shape[0]
    x_read = x  # as recorded: the ringing is read before any interference is subtracted
    s = _subsample(x)
    noise_f = par.submit(_robust_noise, s)
    lo0, hi0, _ = two_means(s)
    hum = np.zeros(-(-n // block))
    if sample_rate_hz and hi0 > lo0:
        cleaned, hum = remove_interference(x, lo0, hi0, noise_f.result(), sample_rate_hz, block)
        if cleaned is not x:  # found and subtracted: the levels and noise of the rest
            x = cleaned
            s = _subsample(x)
            noise_f = par.submit(_robust_noise, s)
            lo0, hi0, _ = two_means(s)
    (lo_b, hi_b, frac_hi, sd_b), rec = par.block_levels(x, block, lo0, hi0, MIN_COUNT)
    check_transitions(x, path, (*kernels.block_extremes(rec), block))
    noise = noise_f.result()
    if not hi0 - lo0 > MIN_SEPARATION * max(noise, 1e-12):
        raise NoContactsError(
            path,
            "no contacts found: the continuity channel shows no transitions between two "
            f"levels (level gap {hi0 - lo0:.3g} V, noise {noise:.3g} V)",
        )
    lo, hi = _fill_levels(lo_b, hi_b, lo0, hi0)
    high = decide_polarity(frac_hi, block, contact_level, rest_intervals, open_intervals)
    open_v, contact_v = (lo, hi) if high else (hi, lo)
    gap = contact_v - open_v
    sd = np.where(np.isfinite(sd_b), sd_b, np.nanmedian(sd_b) if np.isfinite(sd_b).any() else 0)
    q = estimate_q(x, block, open_v, gap, par=par, unmeasured=q_unmeasured)
    sdz = sd / np.abs(gap) * np.sqrt(1.0 + q * q) / (1.0 - q)
    if q >= SLOW_Q:
        sdz = np.minimum(sdz, SLOW_SDZ_CAP * deconvolved_noise(x, block, open_v, gap, q))
    params = (block, open_v, 1.0 / gap, sdz, q, THR_MIN, THR_MAX, 0.0, GLITCH_K)
    t, kind, results, pieces, starts, d_prior = _edge_pass(x, params, par)
    # on the channel as recorded: the subtracted hum estimate bends over the few samples
    # left out around each edge (1-2 mV/sample there against a 2 % hum's 0.5), which
    # read as ringing, 4-5 x the noise, on gain steps under a hum
    ring, n_ring = pre_edge_ringing(x_read, t, block, gap)
    ringing = 0.0
    ring_min = max(RING_NOISE * noise / float(np.median(np.abs(gap))), RING_FLOOR)
    if n_ring >= RING_MIN_EDGES and ring > ring_min:
        # a ringing front end: its lobes are noise to the threshold and the glitch rule
        ringing = ring
        sdz = np.maximum(sdz, ring)
        params = (block, open_v, 1.0 / gap, sdz, q, THR_MIN, THR_MAX, 0.0, GLITCH_K)
        t, kind, results, pieces, starts, d_prior = _edge_pass(x, params, par)
    nb = open_v.shape[0]
    n_glitch = np.zeros(nb, dtype=np.int64)
    n_contact = np.zeros(nb, dtype=np.int64)
    for (a, _), r in zip(pieces, results, strict=True):
        b0 = a // block
        n_glitch[b0 : b0 + r[3].shape[0]] += r[3]
        n_contact[b0 : b0 + r[4].shape[0]] += r[4]
    glitch_at = np.concatenate([r[2] for r in results])[:4096]
    if q == 0.0 and point_sampled(t):
        t = t + 0.5
    if t.size == 0:
        raise NoContactsError(
            path, "no contacts found: no transitions between the two continuity levels"
        )
    return Detection(
        t_edge=t,
        kind=kind,
        first_state=int(starts[0][0]),
        contact_high=bool(high),
        open_v=open_v,
        contact_v=contact_v,
        noise_v=sd,
        q=q,
        d_prior=d_prior,
        n_glitch=n_glitch,
        n_contact=n_contact,
        glitch_at=glitch_at,
        block=block,
        n_samples=int(n),
        interference_v=hum,
        ringing=ringing,
    )


def _edge_pass(x, params, par):
    """Edge times (samples) and kinds of ``x`` under ``params``, with the pieces'
    results, the pieces, their start states and the short-contact prior used."""
    q = params[4]
    # one edge pass with no prior; the prior (the typical duration of short contacts,
    # learnt on the first PRIOR_SAMPLES as the serial code's first pass does) only
    # places the contacts that lie wholly inside one interval, so those are placed
    # again afterwards: the same numbers as a second serial pass with the prior
    results, pieces, starts = par.edges(x, params, cuts=(PRIOR_SAMPLES - 1,))
    t = np.concatenate([r[0] for r in results])
    kind = np.concatenate([r[1] for r in results])
    t_head, k_head = _head_edges(x, results, pieces, starts, params)
    d_prior = _short_contact_prior(t_head, k_head) if q > 0 else 0.0
    if d_prior != 0.0:
        offsets = np.cumsum([0] + [r[0].shape[0] for r in results[:-1]])
        p_at = np.concatenate([r[7] + o for r, o in zip(results, offsets, strict=True)])
        p_k = np.concatenate([r[8] for r in results])
        p_z = np.concatenate([r[9] for r in results])
        kernels.place_pulses(t, p_at, p_k, p_z, q, d_prior)
    return t, kind, results, pieces, starts, d_prior


def _head_edges(x, results, pieces, starts, params):
    """Edges that the serial first pass over ``x[:PRIOR_SAMPLES]`` finds (``d_prior`` 0).

    That pass is the full pass up to iteration ``PRIOR_SAMPLES - 2``; its last iteration
    has no look-ahead (the samples end there), so it is run apart from the state the
    full pass had before it (a piece starts there)."""
    n = x.shape[0]
    if n <= PRIOR_SAMPLES:
        return (
            np.concatenate([r[0] for r in results]),
            np.concatenate([r[1] for r in results]),
        )
    last = PRIOR_SAMPLES - 1
    i = next(j for j, (a, _) in enumerate(pieces) if a == last)
    state, u = starts[i]
    tail = kernels.edge_range(x[:PRIOR_SAMPLES], last, PRIOR_SAMPLES, state, u, *params)
    return (
        np.concatenate([r[0] for r in results[:i]] + [tail[0]]),
        np.concatenate([r[1] for r in results[:i]] + [tail[1]]),
    )
