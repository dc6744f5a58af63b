"""An AC-coupled input (a sound card's line-in), found and undone before the detection.

A continuity circuit is a DC signal: two levels. A sound card's input passes it through
a first-order high-pass (a coupling capacitor; corners of 0.5-20 Hz), so every level
held for long drains towards the running mean: a body resting at Gamma 0.5 reads about
halfway between the levels and then nearer the open one, the `auto` polarity reads the
levels backwards, and the flights are contacts (on the virtual rig through corners of
0.5-20 Hz: none of 358-590 flights right). The high-pass ``y' = x' - y / tau`` is undone
by ``x = y + (1/tau) int y dt``:

* :func:`orphan_share` of a channel is the share of its samples near neither of its two
  levels (within a quarter of the gap): edges only on a DC channel (0.2-1.2 % on the
  rig's recordings, RC front ends to 250 us), up to a quarter where the levels drain;
* :func:`ac_coupling_tau` looks for the time constant only where that share exceeds
  ``SUSPECT_SHARE``: on the first ``SEARCH_S`` seconds, over a grid of ``tau`` from 5 ms
  to 5 s (corners of 0.03-30 Hz; longer ones would "mend" a slow drift of the levels,
  which the block levels follow anyway) by the orphan share of the inverted channel,
  then by the spread of its levels between the grid's neighbours; the inversion is
  taken only where it leaves fewer than ``ACCEPT_SHARE`` of the samples orphaned and
  at most a fifth of the raw share (a gain step, whose orphans no inversion removes,
  stays as it was). A recording that mostly
  bounces drains little (its open level is most of the time anyway): 1.4 % orphaned
  through a 2 Hz corner, 0.2 % once undone;
* :func:`undo_ac_coupling` applies the inverse (trapezoidal integral, float64).

A channel that is not AC-coupled is returned as it is, bit for bit.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import minimize_scalar

from bouncelab.flights.detect import two_means

SUSPECT_SHARE = 0.005  # orphaned share of samples above which an AC coupling is looked for
ACCEPT_SHARE = 0.01  # ... and below which (and a fifth of the raw share) it is undone
GAIN = 5.0  # the inversion must leave at most 1/GAIN of the raw share orphaned
SEARCH_S = 60.0  # seconds of the channel the time constant is read on
TAU_GRID_S = np.logspace(np.log10(0.005), np.log10(5.0), 25)  # 5 ms to 5 s (corners 0.03-30 Hz)


def orphan_share(x: np.ndarray) -> float:
    """Share of the samples of ``x`` (n,) farther than a quarter of the level gap from
    both of its two-means levels."""
    lo, hi, _ = two_means(x)
    g = hi - lo
    if not g > 0:
        return 0.0
    return float(np.mean((np.abs(x - lo) > 0.25 * g) & (np.abs(x - hi) > 0.25 * g)))


def undo_ac_coupling(y: np.ndarray, fs: float, tau_s: float) -> np.ndarray:
    """The DC signal (n,) float64 behind ``y`` (n,), sampled at ``fs`` Hz, seen through
    a first-order high-pass of time constant ``tau_s``: ``x = y + (1/tau) int_0^t y``
    (trapezoidal rule; the constant of integration is the first sample's level)."""
    y = np.asarray(y, dtype=np.float64)
    c = np.cumsum(y)
    return y + (c - 0.5 * (y[0] + y)) / (fs * tau_s)


def _level_spread(x: np.ndarray) -> float:
    lo, hi, sd = two_means(x)
    return sd / max(hi - lo, 1e-300)


def ac_coupling_tau(x: np.ndarray, fs: float) -> float | None:
    """Time constant (s) of a first-order AC coupling of the channel ``x`` (n,), or None
    where the channel shows none (module docstring)."""
    y = np.asarray(x[: int(SEARCH_S * fs)], dtype=np.float64)
    if y.shape[0] < 1000:
        return None
    raw = orphan_share(y)
    if raw <= SUSPECT_SHARE:
        return None
    shares = np.array([orphan_share(undo_ac_coupling(y, fs, t)) for t in TAU_GRID_S])
    i = int(np.argmin(shares))
    lo, hi = np.log(TAU_GRID_S[max(i - 1, 0)]), np.log(TAU_GRID_S[min(i + 1, len(TAU_GRID_S) - 1)])
    best = minimize_scalar(
        lambda lt: _level_spread(undo_ac_coupling(y, fs, float(np.exp(lt)))),
        bounds=(lo, hi),
        method="bounded",
        options={"xatol": 0.01},
    )
    tau = float(np.exp(best.x))
    share = orphan_share(undo_ac_coupling(y, fs, tau))
    if share > min(shares[i], ACCEPT_SHARE) * 1.5 and shares[i] < share:
        tau, share = float(TAU_GRID_S[i]), float(shares[i])  # the refinement lost its way
    if share >= ACCEPT_SHARE or share * GAIN > raw:
        return None
    return tau
