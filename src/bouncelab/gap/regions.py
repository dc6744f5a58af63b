"""Where the gap lies: the per-step gap over Gamma cut into regions of similar size.

The profile (by default ``log(1 + rel_gap)`` per step, in Gamma order) is segmented by
optimal partitioning: the exact minimum over all cuts of the within-region sum of
squared deviations from the region mean, plus a penalty per region, every region at
least ``min_steps`` steps wide (dynamic programming, O(S^2) for S steps; deterministic).
The log makes "similar size" mean "similar ratio": a gap of 10 floors next to one of 12
is one region, 1 next to 3 is two, and the larger noise of large gaps does not create
regions. The default penalty is ``3 sigma^2 ln S`` (a BIC-type penalty, a little
stricter), with ``sigma`` the robust noise of the profile from its step-to-step
differences (``1.4826 MAD / sqrt 2``), but at least ``min_sigma`` = 0.15 on the log
profile: a smooth, nearly noiseless profile (a model off by a slowly growing amount)
would otherwise be cut into dozens of regions that differ by a few per cent; with the
floor, a region boundary needs a change of the gap by some 15 % or more.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from bouncelab.gap.distances import step_weights
from bouncelab.gap.features import gamma_differs

#: Smallest region width (steps).
DEFAULT_MIN_STEPS = 3

#: Penalty per region in units of ``sigma^2 ln S``.
DEFAULT_PENALTY_FACTOR = 3.0

#: Smallest noise level assumed for the log profile (``log(1 + rel_gap)`` units).
DEFAULT_MIN_SIGMA = 0.15

#: A per-step feature difference is named for a region when at least this share of the
#: region's steps show it (single flickering steps are not a feature of a region).
DEFAULT_FEATURE_SHARE = 1.0 / 3.0

PER_STEP_FEATURES = {
    "differs_sticking": "sticking",
    "differs_clusters": "clusters",
    "differs_locking": "locking",
    "differs_chatter": "chatter_share",
    "differs_phase": "phase_offset",
}
GAMMA_FEATURES = ("takeoff_onset", "doubling_2", "doubling_4")


def robust_noise(y: np.ndarray) -> float:
    """Noise level of a profile from its first differences: ``1.4826 MAD(diff) / sqrt(2)``.

    Insensitive to a few level changes. Units of ``y``; 0 for fewer than 3 values.
    """
    y = np.asarray(y, dtype=np.float64)
    if len(y) < 3:
        return 0.0
    d = np.diff(y)
    return float(1.4826 * np.median(np.abs(d - np.median(d))) / np.sqrt(2.0))


def default_penalty(
    y: np.ndarray, factor: float = DEFAULT_PENALTY_FACTOR, min_sigma: float = 0.0
) -> float:
    """``factor * max(sigma, min_sigma)^2 * ln(S)`` for ``S`` values (units of ``y^2``).

    ``sigma`` is :func:`robust_noise`. A tiny positive floor keeps a noiseless profile
    from splitting at every step.
    """
    y = np.asarray(y, dtype=np.float64)
    sigma = max(robust_noise(y), min_sigma)
    floor = 1e-12 * max(float(np.var(y)), 1.0)
    return max(factor * sigma**2 * np.log(max(len(y), 2)), floor)


def segment_profile(
    y: np.ndarray,
    *,
    min_size: int = DEFAULT_MIN_STEPS,
    penalty: float | None = None,
    min_sigma: float = 0.0,
) -> list[tuple[int, int]]:
    """Optimal partition of a 1-D profile into constant-mean segments.

    Minimises ``sum over segments (SSE around the segment mean + penalty)`` exactly,
    every segment at least ``min_size`` long (a shorter profile is one segment).

    Parameters
    ----------
    y : array_like, shape (S,)
        the profile, finite.
    min_size : int
        smallest segment length.
    penalty : float, optional
        cost of one more segment (units of ``y^2``); :func:`default_penalty` (with
        ``min_sigma``) if None.

    Returns
    -------
    list of ``(start, stop)`` index pairs (stop exclusive), covering ``0..S`` in order.
    """
    y = np.asarray(y, dtype=np.float64)
    n = len(y)
    if min_size < 1:
        raise ValueError("min_size must be at least 1")
    if n == 0:
        return []
    if n < 2 * min_size:
        return [(0, n)]
    beta = default_penalty(y, min_sigma=min_sigma) if penalty is None else float(penalty)
    c1 = np.concatenate([[0.0], np.cumsum(y)])
    c2 = np.concatenate([[0.0], np.cumsum(y * y)])
    best = np.full(n + 1, np.inf)
    best[0] = -beta
    last = np.zeros(n + 1, dtype=np.int64)
    for t in range(min_size, n + 1):
        # candidate starts s: 0, or min_size <= s <= t - min_size
        s = np.concatenate([[0], np.arange(min_size, t - min_size + 1)])
        length = t - s
        sse = (c2[t] - c2[s]) - (c1[t] - c1[s]) ** 2 / length
        cost = best[s] + np.maximum(sse, 0.0) + beta
        k = int(np.argmin(cost))  # first minimum: ties go to the earliest start
        best[t] = cost[k]
        last[t] = s[k]
    cuts = []
    t = n
    while t > 0:
        cuts.append((int(last[t]), t))
        t = int(last[t])
    return cuts[::-1]


def _region_features(
    per_step: pd.DataFrame | None, cmp: dict | None, lo: float, hi: float, share: float
) -> tuple[list[str], dict]:
    """Feature names that differ inside ``[lo, hi]`` (Gamma) and the per-step shares."""
    if per_step is None or cmp is None:
        return [], {}
    inside = per_step[(per_step["gamma"] >= lo) & (per_step["gamma"] <= hi)]
    names, shares = [], {}
    for col, name in PER_STEP_FEATURES.items():
        if col in inside.columns and len(inside):
            frac = float(inside[col].to_numpy(dtype=bool).mean())
            shares[name] = frac
            if frac >= share:
                names.append(name)
    for key in GAMMA_FEATURES:
        a, b = cmp[key]["data"], cmp[key]["sim"]
        if not gamma_differs(a, b, cmp.get("gamma_tol", 0.0)):
            continue  # the same on both sides, within the grid's resolution
        if any(g is not None and lo <= g <= hi for g in (a, b)):
            names.append(key)
    return names, shares


def segment_regions(
    table: pd.DataFrame,
    cmp: dict | None = None,
    *,
    column: str | None = None,
    min_steps: int = DEFAULT_MIN_STEPS,
    penalty: float | None = None,
    log: bool = True,
    min_sigma: float | None = None,
    feature_share: float = DEFAULT_FEATURE_SHARE,
    weights: str = "equal",
) -> list[dict]:
    """Regions of similar gap over Gamma, each with its size and the features that differ.

    Parameters
    ----------
    table : DataFrame
        a gap table (:func:`bouncelab.gap.gap_table`), best with the floor columns of
        :func:`bouncelab.gap.relative_gap`.
    cmp : dict, optional
        :func:`bouncelab.gap.compare_features` of the same data and simulation; gives
        each region its differing features.
    column : str, optional
        the profile to segment: ``rel_gap`` when the table has it, else ``gap``.
    min_steps : int
        smallest region width (steps).
    penalty : float, optional
        cost per region, units of the (log) profile squared; default
        :func:`default_penalty`.
    log : bool
        segment ``log(1 + value)`` rather than the value.
    min_sigma : float, optional
        smallest profile noise in the default penalty; :data:`DEFAULT_MIN_SIGMA` for
        the log profile, 0 otherwise.
    feature_share : float
        share of a region's steps that must show a per-step difference.
    weights : ``"equal"`` or ``"gamma"``, how steps are averaged within a region.

    Returns
    -------
    list of dicts in Gamma order: ``gamma_min``, ``gamma_max``, ``step_min``,
    ``step_max``, ``n_steps``, ``gap`` (rad, weighted mean), ``floor`` (rad) and
    ``rel_gap`` (mean gap / mean ``floor_used``, i.e. the floor raised to ``min_floor``)
    when the table has a floor, ``features`` (names that
    differ), ``feature_shares`` (share of steps per per-step feature),
    ``explained_by`` (None; filled by effect selection).
    """
    if column is None:
        column = "rel_gap" if "rel_gap" in table.columns else "gap"
    tab = table.loc[np.isfinite(table[column].to_numpy(dtype=np.float64))]
    tab = tab.sort_values(["gamma", "step"], kind="stable").reset_index(drop=True)
    values = tab[column].to_numpy(dtype=np.float64)
    y = np.log1p(np.maximum(values, 0.0)) if log else values
    per_step = cmp["per_step"] if cmp is not None else None
    regions = []
    if min_sigma is None:
        min_sigma = DEFAULT_MIN_SIGMA if log else 0.0
    cuts = segment_profile(y, min_size=min_steps, penalty=penalty, min_sigma=min_sigma)
    for lo, hi in cuts:
        part = tab.iloc[lo:hi]
        w = step_weights(part, weights)
        gam = part["gamma"].to_numpy(dtype=np.float64)
        region = {
            "gamma_min": float(np.min(gam)),
            "gamma_max": float(np.max(gam)),
            "step_min": int(part["step"].min()),
            "step_max": int(part["step"].max()),
            "n_steps": int(hi - lo),
            "gap": float(np.sum(w * part["gap"].to_numpy(dtype=np.float64))),
        }
        if "floor" in part.columns:
            region["floor"] = float(np.sum(w * part["floor"].to_numpy(dtype=np.float64)))
            used = part["floor_used"] if "floor_used" in part.columns else part["floor"]
            floor = float(np.sum(w * used.to_numpy(dtype=np.float64)))
            region["rel_gap"] = region["gap"] / floor if floor > 0 else float("nan")
        names, shares = _region_features(
            per_step, cmp, region["gamma_min"], region["gamma_max"], feature_share
        )
        region["features"] = names
        region["feature_shares"] = shares
        region["explained_by"] = None
        regions.append(region)
    return regions
