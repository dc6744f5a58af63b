"""Contacts and flights from a continuity channel: levels, polarity, RC constant, edges.

:func:`detect_contacts` is a pure function of a sample array (volts) and a few hints;
it returns a :class:`Detection` with sub-sample edge times in samples.  The heavy work
is in the numba kernels of :mod:`bouncelab.flights.kernels`; this module arranges them.

Rules (docs/flights.md has the full story):

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
* Detection threshold on the deconvolved contact fraction ``z``: ``clip(6 sigma_z,
  0.12, 0.45)``; a contact that fills less than that share of one sample interval is
  not seen (about 6 us at 20 kHz with the usual RC front end), and the two flights
  around it merge into one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bouncelab.errors import BouncelabError
from bouncelab.flights import kernels

BLOCK = 4096  # samples per level block (0.2 s at 20 kHz): drift is much slower
MIN_COUNT = 32  # samples a level needs in a block to be trusted there
THR_MIN, THR_MAX = 0.12, 0.45  # bounds of the threshold on z, fraction of the gap
GLITCH_K = 6.0  # noise multiples of the glitch rules
MIN_SEPARATION = 10.0  # level gap / noise below which there are no two levels
PRIOR_SAMPLES = 2_000_000  # samples used to learn the typical short-contact duration


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


def check_transitions(x: np.ndarray, path=None) -> None:
    """Raise :class:`BouncelabError` when ``x`` is stuck at one value or has no two levels."""
    xmin, xmax = float(np.min(x)), float(np.max(x))
    n = x.shape[0]
    if xmax == xmin:
        raise BouncelabError(
            path, f"continuity channel is stuck at one rail ({xmin:.6g} V in every sample)"
        )
    n_at = max(np.count_nonzero(x == xmin), np.count_nonzero(x == xmax))
    if n_at >= 0.99 * n:
        rail = xmin if np.count_nonzero(x == xmin) >= np.count_nonzero(x == xmax) else xmax
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


def estimate_q(x, block, open_b, gap_b, max_ratios: int = 200_000) -> float:
    """RC decay per sample from clean edges (median ratio), 0 when not measurable."""
    # a prefix usually holds enough clean edges; the whole recording only if it does not
    inv = 1.0 / gap_b
    r = kernels.rc_ratios(x[:PRIOR_SAMPLES], block, open_b, inv, max_ratios)
    if r.size < 200 and x.shape[0] > PRIOR_SAMPLES:
        r = kernels.rc_ratios(x, block, open_b, inv, max_ratios)
    r = r[np.isfinite(r)]
    if r.size < 8:
        return 0.0
    q = float(np.median(r))
    return 0.0 if q < kernels.Q_MIN else min(q, 0.9)


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


def detect_contacts(
    x: np.ndarray,
    contact_level: str = "auto",
    rest_intervals=(),
    open_intervals=(),
    block: int = BLOCK,
    path=None,
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

    Raises
    ------
    BouncelabError
        The channel is stuck at one rail, or shows no transitions ("no contacts found").
    """
    x = np.ascontiguousarray(x)
    if x.shape[0] < 3:
        raise BouncelabError(path, "continuity channel has fewer than 3 samples")
    check_transitions(x, path)
    lo0, hi0, _ = two_means(x)
    noise = _robust_noise(x)
    if not hi0 - lo0 > MIN_SEPARATION * max(noise, 1e-12):
        raise NoContactsError(
            path,
            "no contacts found: the continuity channel shows no transitions between two "
            f"levels (level gap {hi0 - lo0:.3g} V, noise {noise:.3g} V)",
        )
    lo_b, hi_b, frac_hi, sd_b = kernels.block_levels(x, block, lo0, hi0, MIN_COUNT)
    lo, hi = _fill_levels(lo_b, hi_b, lo0, hi0)
    high = decide_polarity(frac_hi, block, contact_level, rest_intervals, open_intervals)
    open_v, contact_v = (lo, hi) if high else (hi, lo)
    gap = contact_v - open_v
    sd = np.where(np.isfinite(sd_b), sd_b, np.nanmedian(sd_b) if np.isfinite(sd_b).any() else 0)
    q = estimate_q(x, block, open_v, gap)
    sdz = sd / np.abs(gap) * np.sqrt(1.0 + q * q) / (1.0 - q)
    # first pass on a prefix learns the duration of short contacts (the prior that
    # places a contact lying wholly inside one sample interval)
    head = x[:PRIOR_SAMPLES]
    t0, k0, *_ = kernels.detect_edges(
        head, block, open_v, 1.0 / gap, sdz, q, THR_MIN, THR_MAX, 0.0, GLITCH_K
    )
    d_prior = _short_contact_prior(t0, k0) if q > 0 else 0.0
    t, kind, n_glitch, n_contact, first, glitch_at = kernels.detect_edges(
        x, block, open_v, 1.0 / gap, sdz, q, THR_MIN, THR_MAX, d_prior, GLITCH_K
    )
    if t.size == 0:
        raise NoContactsError(
            path, "no contacts found: no transitions between the two continuity levels"
        )
    return Detection(
        t_edge=t,
        kind=kind,
        first_state=int(first),
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
        n_samples=int(x.shape[0]),
    )
