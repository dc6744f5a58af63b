"""Named features of a flight table over Gamma, and how data and simulation differ in them.

Computed on settled flights (when ``settled`` is present), one table at a time:

takeoff onset
    the lowest Gamma of a step with at least ``min_flights`` flights (the body leaves
    the plate). Ideal ball: Gamma = 1; Coulomb friction moves it to 1 + mu.
flight-time clusters and period doublings
    the number of distinct flight-time clusters per step (chatter flights left out): a
    cut wherever the sorted flight times jump by more than ``gap_factor`` times their
    median spacing (and more than ``cluster_tol``); clusters with fewer than
    ``min_share`` of the flights are dropped as strays. A period-n orbit gives n
    clusters; a chaotic band, whose spacings are all alike, gives one. A doubling is a
    step whose count reaches ``k`` (2, 4, ...) right after a step with a count below
    ``k``; its Gamma is that step's Gamma.
locking plateaus
    steps where at least ``lock_share`` of the flights lie within ``lock_tol`` of
    ``2 pi n`` for one ``n >= 1`` (the ideal ball locks at ``T = 2 pi n`` from
    ``Gamma_n = sqrt(1 + n^2 pi^2)``); a plateau is a run of consecutive locked steps
    with the same ``n``.
chatter share
    the share of flights that are both tiny (``T < chatter_T``, rad) and much shorter
    than the long flights of their step (``T < chatter_rel`` x the 90th percentile of
    the step's T): the second condition keeps the short flights just above takeoff
    onset from counting as chatter. With ``use_chatter_column`` the table's own
    ``chatter`` column is used where present (the simulator marks chatter exactly; the
    rule applies to both sides by default so that they are measured alike).
takeoff phase
    circular mean of ``phi_takeoff`` per step (rad), chatter left out; the offset
    between data and simulation is wrapped to ``(-pi, pi]``. NaN without a drive channel.
repeat
    how closely a step's flights (in order, chatter left out) repeat: the least, over
    periods ``p = 1 .. repeat_max_period``, of the median ``|T[n+p] - T[n]|`` (rad).
    A periodic orbit of a deterministic model repeats to within the timing noise
    (microseconds); a chaotic band does not repeat at all; a periodic orbit shaken by a
    random force repeats only to within the force's scatter.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
import pandas as pd

from bouncelab.gap.distances import _check_table, _flight_arrays, flight_order, step_grid

TWO_PI = 2.0 * np.pi


@dataclass(frozen=True)
class FeatureOptions:
    """Thresholds of the features; units in the names' comments.

    min_flights : flights a step needs to count as "the body flies" (onset).
    gap_factor : cluster cut = jump > gap_factor x median spacing of sorted T.
    cluster_tol : rad, smallest jump that cuts clusters (exactly periodic samples have
        median spacing 0).
    min_share : smallest share of a step's flights that makes a cluster.
    lock_tol : rad, distance of T to 2 pi n that counts as locked.
    lock_share : share of a step's flights that must be locked.
    chatter_T : rad, chatter flights are shorter than this ...
    chatter_rel : ... and shorter than this times the step's 90th percentile of T.
    use_chatter_column : take the ``chatter`` column where a table has it.
    chatter_tol : difference in chatter share that counts as differing.
    phase_tol : rad, takeoff-phase offset that counts as differing.
    gamma_tol : difference in Gamma (onset, doublings, plateau edges) that counts as
        differing; None: 1.5 x the median spacing of the step grid, so that one step of
        disagreement at a boundary (the grid's resolution) is not a difference.
    repeat_max_period : longest period (flights) the repeat of a step is read at.
    """

    min_flights: int = 3
    gap_factor: float = 20.0
    cluster_tol: float = 0.05
    min_share: float = 0.05
    lock_tol: float = 0.05
    lock_share: float = 0.9
    chatter_T: float = 0.1
    chatter_rel: float = 0.25
    use_chatter_column: bool = False
    chatter_tol: float = 0.05
    phase_tol: float = 0.1
    gamma_tol: float | None = None
    repeat_max_period: int = 8


def count_clusters(
    t: np.ndarray,
    *,
    gap_factor: float = FeatureOptions.gap_factor,
    cluster_tol: float = FeatureOptions.cluster_tol,
    min_share: float = FeatureOptions.min_share,
) -> tuple[int, float]:
    """Number of distinct flight-time clusters in one step, and their spread.

    Parameters
    ----------
    t : array_like, shape (n,)
        flight times of one step, rad, any order.

    Returns
    -------
    (count, spread): count of clusters holding at least ``max(2, min_share * n)``
    flights (a single flight counts as one cluster); spread is the median absolute
    deviation of the flights from their cluster's median (rad), 0 for exact orbits and
    large for chaotic bands. ``(0, nan)`` for no flights.
    """
    t = np.sort(np.asarray(t, dtype=np.float64))
    n = len(t)
    if n == 0:
        return 0, float("nan")
    if n == 1:
        return 1, 0.0
    jumps = np.diff(t)
    cut = jumps > max(cluster_tol, gap_factor * float(np.median(jumps)))
    label = np.concatenate([[0], np.cumsum(cut)])
    sizes = np.bincount(label)
    big = sizes >= max(2.0, min_share * n)
    count = int(np.count_nonzero(big))
    keep = big[label]
    if count == 0:  # only strays: a scatter of single flights, treat as one broad band
        return 1, float(np.median(np.abs(t - np.median(t))))
    medians = np.array([np.median(t[label == k]) for k in range(len(sizes))])
    spread = float(np.median(np.abs(t[keep] - medians[label[keep]])))
    return count, spread


def chatter_mask(
    step: np.ndarray, t: np.ndarray, opts: FeatureOptions = FeatureOptions()
) -> np.ndarray:
    """Flights that count as chatter by the rule of the module docstring.

    Parameters
    ----------
    step, t : ndarray, shape (n,): step index and flight time (rad) of each flight.

    Returns
    -------
    ndarray of bool, shape (n,).
    """
    mask = np.zeros(len(t), dtype=bool)
    tiny = t < opts.chatter_T
    if not tiny.any():
        return mask
    for s in np.unique(step[tiny]):
        in_step = step == s
        q90 = np.quantile(t[in_step], 0.9)
        mask[in_step] = tiny[in_step] & (t[in_step] < opts.chatter_rel * q90)
    return mask


def locked_order(t: np.ndarray, opts: FeatureOptions = FeatureOptions()) -> int:
    """The ``n`` of a step locked at ``T = 2 pi n``, or 0 when it is not locked.

    Parameters
    ----------
    t : ndarray, shape (n,): flight times of one step (rad), chatter left out.
    """
    if len(t) == 0:
        return 0
    n = np.rint(t / TWO_PI)
    near = (n >= 1) & (np.abs(t - TWO_PI * n) < opts.lock_tol)
    if np.count_nonzero(near) < opts.lock_share * len(t):
        return 0
    values, counts = np.unique(n[near], return_counts=True)
    best = int(values[np.argmax(counts)])
    return best if counts.max() >= opts.lock_share * len(t) else 0


def repeat_error(t: np.ndarray, max_period: int = FeatureOptions.repeat_max_period) -> float:
    """How closely the flights of one step repeat (rad): the least, over periods
    ``p = 1 .. max_period``, of the median ``|t[n+p] - t[n]|``; NaN with fewer than
    ``max_period + 8`` flights (a median over at least 8 pairs at every period).

    Parameters
    ----------
    t : ndarray, shape (n,): flight times of one step in the order flown (rad), chatter
        left out.
    """
    t = np.asarray(t, dtype=np.float64)
    if t.shape[0] < max_period + 8:
        return float("nan")
    return float(min(np.median(np.abs(t[p:] - t[:-p])) for p in range(1, max_period + 1)))


def circular_mean(phi: np.ndarray) -> tuple[float, float]:
    """Circular mean (rad, in ``(-pi, pi]``) and resultant length (0..1) of angles.

    ``(nan, nan)`` for no finite angles.
    """
    phi = np.asarray(phi, dtype=np.float64)
    phi = phi[np.isfinite(phi)]
    if len(phi) == 0:
        return float("nan"), float("nan")
    c, s = np.mean(np.cos(phi)), np.mean(np.sin(phi))
    return float(np.arctan2(s, c)), float(np.hypot(c, s))


def wrap_angle(x: np.ndarray | float) -> np.ndarray | float:
    """Angle difference wrapped to ``(-pi, pi]`` (rad)."""
    return np.pi - np.mod(np.pi - np.asarray(x, dtype=np.float64), TWO_PI)


def step_features(
    table: pd.DataFrame,
    *,
    steps: pd.DataFrame | np.ndarray | None = None,
    settled_only: bool = True,
    opts: FeatureOptions = FeatureOptions(),
    name: str = "flights",
) -> pd.DataFrame:
    """Per-step features of one flight table.

    Parameters
    ----------
    table : DataFrame with ``step``, ``gamma``, ``T``; optional ``settled``,
        ``phi_takeoff``, ``chatter``.
    steps : steps to report (see :func:`bouncelab.gap.distances.step_grid`); steps
        without flights get ``n = 0``.

    Returns
    -------
    DataFrame, one row per step, ascending: ``step``, ``gamma``, ``n`` (flights),
    ``T_median`` (rad), ``chatter_share``, ``n_clusters``, ``spread`` (rad),
    ``locked_n`` (0: not locked), ``phase_mean`` (rad), ``phase_R``, ``repeat`` (rad,
    :func:`repeat_error`).
    """
    _check_table(table, name)
    table = table.iloc[flight_order(table)]  # each step's flights in the order flown
    step, t, settled = _flight_arrays(table, name)
    keep = settled if settled_only else np.ones(len(t), dtype=bool)
    phi = (
        table["phi_takeoff"].to_numpy(dtype=np.float64)
        if "phi_takeoff" in table.columns
        else np.full(len(t), np.nan)
    )
    chat_col = None
    if opts.use_chatter_column and "chatter" in table.columns:
        chat_col = table["chatter"].to_numpy(dtype=bool)[keep]
    step, t, phi = step[keep], t[keep], phi[keep]
    chatter = chat_col if chat_col is not None else chatter_mask(step, t, opts)

    grid, gammas = step_grid(table, steps=steps)
    order = np.argsort(step, kind="stable")  # stable: each step's flights stay in order
    step, t, phi, chatter = step[order], t[order], phi[order], chatter[order]
    bounds = np.searchsorted(step, np.stack([grid, grid + 1]))

    rows = []
    for k, s in enumerate(grid):
        lo, hi = bounds[0, k], bounds[1, k]
        ts, ch = t[lo:hi], chatter[lo:hi]
        main = ts[~ch]
        n_clusters, spread = count_clusters(
            main, gap_factor=opts.gap_factor, cluster_tol=opts.cluster_tol,
            min_share=opts.min_share,
        )  # fmt: skip
        phase_mean, phase_r = circular_mean(phi[lo:hi][~ch])
        rows.append(
            (
                s,
                gammas[k],
                hi - lo,
                float(np.median(ts)) if hi > lo else np.nan,
                float(np.mean(ch)) if hi > lo else np.nan,
                n_clusters,
                spread,
                locked_order(main, opts),
                phase_mean,
                phase_r,
                repeat_error(main, opts.repeat_max_period),
            )
        )
    columns = [
        "step", "gamma", "n", "T_median", "chatter_share", "n_clusters", "spread",
        "locked_n", "phase_mean", "phase_R", "repeat",
    ]  # fmt: skip
    return pd.DataFrame(rows, columns=columns).astype(
        {"step": np.int64, "n": np.int64, "n_clusters": np.int64, "locked_n": np.int64}
    )


def takeoff_onset(per_step: pd.DataFrame, min_flights: int = FeatureOptions.min_flights):
    """Lowest Gamma of a step with at least ``min_flights`` flights; None if none."""
    flying = per_step.loc[per_step["n"] >= min_flights, "gamma"]
    return float(flying.min()) if len(flying) else None


def period_doublings(per_step: pd.DataFrame) -> list[dict]:
    """Steps where the cluster count at least doubles from the previous step with flights.

    Steps are taken in order of Gamma; steps without flights are skipped (they neither
    start nor break a sequence).

    Returns
    -------
    list of ``{"gamma": float, "step": int, "from": int, "to": int}``, in Gamma order.
    """
    ps = per_step.loc[per_step["n_clusters"] > 0].sort_values("gamma", kind="stable")
    counts = ps["n_clusters"].to_numpy()
    out = []
    for i in range(1, len(ps)):
        if counts[i] >= 2 * counts[i - 1]:
            out.append(
                {
                    "gamma": float(ps["gamma"].iloc[i]),
                    "step": int(ps["step"].iloc[i]),
                    "from": int(counts[i - 1]),
                    "to": int(counts[i]),
                }
            )
    return out


def first_doubling(per_step: pd.DataFrame, k: int) -> float | None:
    """Gamma of the first step whose cluster count reaches ``k`` from below ``k``."""
    ps = per_step.loc[per_step["n_clusters"] > 0].sort_values("gamma", kind="stable")
    counts = ps["n_clusters"].to_numpy()
    hits = np.flatnonzero((counts[1:] >= k) & (counts[:-1] < k))
    return float(ps["gamma"].iloc[hits[0] + 1]) if len(hits) else None


def locking_plateaus(per_step: pd.DataFrame) -> list[dict]:
    """Runs of consecutive steps (in Gamma order) locked at the same ``n``.

    Returns
    -------
    list of ``{"n": int, "gamma_min": float, "gamma_max": float, "n_steps": int}``.
    """
    ps = per_step.sort_values("gamma", kind="stable")
    locked = ps["locked_n"].to_numpy()
    gam = ps["gamma"].to_numpy(dtype=np.float64)
    out = []
    i = 0
    while i < len(ps):
        if locked[i] == 0:
            i += 1
            continue
        j = i
        while j + 1 < len(ps) and locked[j + 1] == locked[i]:
            j += 1
        out.append(
            {
                "n": int(locked[i]),
                "gamma_min": float(gam[i]),
                "gamma_max": float(gam[j]),
                "n_steps": j - i + 1,
            }
        )
        i = j + 1
    return out


def features(
    table: pd.DataFrame,
    *,
    steps: pd.DataFrame | np.ndarray | None = None,
    settled_only: bool = True,
    opts: FeatureOptions = FeatureOptions(),
    name: str = "flights",
) -> dict:
    """All named features of one flight table.

    Returns
    -------
    dict with ``per_step`` (DataFrame of :func:`step_features`), ``takeoff_onset``
    (Gamma or None), ``doublings`` (list, :func:`period_doublings`), ``first_doubling``
    (``{2: Gamma or None, 4: ...}``), ``plateaus`` (list, :func:`locking_plateaus`),
    ``chatter_share`` (share over all settled flights, NaN without flights),
    ``options`` (the thresholds used).
    """
    per_step = step_features(table, steps=steps, settled_only=settled_only, opts=opts, name=name)
    n = per_step["n"].to_numpy()
    share = per_step["chatter_share"].to_numpy()
    total = n.sum()
    return {
        "per_step": per_step,
        "takeoff_onset": takeoff_onset(per_step, opts.min_flights),
        "doublings": period_doublings(per_step),
        "first_doubling": {k: first_doubling(per_step, k) for k in (2, 4)},
        "plateaus": locking_plateaus(per_step),
        "chatter_share": float(np.nansum(share * n) / total) if total else float("nan"),
        "options": asdict(opts),
    }


def _diff(a, b) -> dict:
    """``{"data", "sim", "diff"}`` with ``diff = sim - data`` (None when either is None)."""
    diff = None if a is None or b is None else float(b) - float(a)
    return {"data": a, "sim": b, "diff": diff}


def compare_features(
    data: pd.DataFrame,
    sim: pd.DataFrame,
    *,
    steps: pd.DataFrame | np.ndarray | None = None,
    settled_only: bool = True,
    opts: FeatureOptions = FeatureOptions(),
) -> dict:
    """The named features of data and simulation side by side, and which differ.

    Parameters
    ----------
    data, sim : flight tables (see :func:`step_features`); compared on the joined steps.

    Returns
    -------
    dict with
    ``per_step``: DataFrame, one row per step: ``step``, ``gamma``, ``n_data``,
    ``n_sim``, ``clusters_data``, ``clusters_sim``, ``locked_data``, ``locked_sim``,
    ``chatter_data``, ``chatter_sim``, ``phase_offset`` (rad, sim - data, wrapped),
    ``repeat_data``, ``repeat_sim`` (rad, :func:`repeat_error`), and
    booleans ``differs_sticking`` (one side flies, the other not), ``differs_clusters``,
    ``differs_locking``, ``differs_chatter``, ``differs_phase``;
    ``takeoff_onset``, ``doubling_2``, ``doubling_4``, ``chatter_share``: each
    ``{"data", "sim", "diff"}`` (Gamma or share; diff = sim - data);
    ``plateaus``: ``{"data": [...], "sim": [...]}``;
    ``phase_offset``: ``{"mean": rad, "max_abs": rad}`` over steps where both fly;
    ``differing``: sorted names of the features that differ.
    """
    if steps is None:
        _check_table(data, "data")
        _check_table(sim, "simulation")
        grid, gammas = step_grid(data, sim)
        steps = pd.DataFrame({"step": grid, "gamma": gammas})
    kw = {"steps": steps, "settled_only": settled_only, "opts": opts}
    fd = features(data, name="data", **kw)
    fs = features(sim, name="simulation", **kw)
    pd_, ps_ = fd["per_step"], fs["per_step"]

    offset = wrap_angle(ps_["phase_mean"].to_numpy() - pd_["phase_mean"].to_numpy())
    fly_d, fly_s = pd_["n"].to_numpy() > 0, ps_["n"].to_numpy() > 0
    both = fly_d & fly_s
    clusters_d, clusters_s = pd_["n_clusters"].to_numpy(), ps_["n_clusters"].to_numpy()
    chat_diff = np.abs(ps_["chatter_share"].to_numpy() - pd_["chatter_share"].to_numpy())
    per_step = pd.DataFrame(
        {
            "step": pd_["step"],
            "gamma": pd_["gamma"],
            "n_data": pd_["n"],
            "n_sim": ps_["n"],
            "clusters_data": pd_["n_clusters"],
            "clusters_sim": ps_["n_clusters"],
            "locked_data": pd_["locked_n"],
            "locked_sim": ps_["locked_n"],
            "chatter_data": pd_["chatter_share"],
            "chatter_sim": ps_["chatter_share"],
            "phase_offset": offset,
            "repeat_data": pd_["repeat"],
            "repeat_sim": ps_["repeat"],
            "differs_sticking": fly_d != fly_s,
            "differs_clusters": both & (clusters_d != clusters_s),
            "differs_locking": pd_["locked_n"].to_numpy() != ps_["locked_n"].to_numpy(),
            "differs_chatter": both & (chat_diff > opts.chatter_tol),
            "differs_phase": both & (np.abs(np.nan_to_num(offset)) > opts.phase_tol),
        }
    )
    finite = both & np.isfinite(offset)
    phase = {
        "mean": circular_mean(offset[finite])[0] if finite.any() else None,
        "max_abs": float(np.max(np.abs(offset[finite]))) if finite.any() else None,
    }
    out = {
        "per_step": per_step,
        "takeoff_onset": _diff(fd["takeoff_onset"], fs["takeoff_onset"]),
        "doubling_2": _diff(fd["first_doubling"][2], fs["first_doubling"][2]),
        "doubling_4": _diff(fd["first_doubling"][4], fs["first_doubling"][4]),
        "chatter_share": _diff(fd["chatter_share"], fs["chatter_share"]),
        "plateaus": {"data": fd["plateaus"], "sim": fs["plateaus"]},
        "phase_offset": phase,
    }
    gam = np.unique(per_step["gamma"].to_numpy(dtype=np.float64))
    gam = gam[np.isfinite(gam)]
    spacing = float(np.median(np.diff(gam))) if len(gam) > 1 else 0.0
    out["gamma_tol"] = opts.gamma_tol if opts.gamma_tol is not None else 1.5 * spacing
    out["differing"] = differing_features(out, opts)
    return out


def differing_features(cmp: dict, opts: FeatureOptions = FeatureOptions()) -> list[str]:
    """Names of the features that differ in a :func:`compare_features` result.

    A Gamma feature (onset, doublings) differs when only one side names a Gamma or the
    two differ by more than ``cmp["gamma_tol"]``; ``locking`` when the plateaus differ
    in their orders ``n`` or an edge moves by more than ``gamma_tol``; the chatter
    share by more than ``opts.chatter_tol``; the takeoff phase when the mean offset
    exceeds ``opts.phase_tol``.
    """
    tol = cmp.get("gamma_tol", 0.0)
    names = []
    for key in ("takeoff_onset", "doubling_2", "doubling_4"):
        if gamma_differs(cmp[key]["data"], cmp[key]["sim"], tol):
            names.append(key)
    if plateaus_differ(cmp["plateaus"]["data"], cmp["plateaus"]["sim"], tol):
        names.append("locking")
    d = cmp["chatter_share"]["diff"]
    if d is not None and np.isfinite(d) and abs(d) > opts.chatter_tol:
        names.append("chatter_share")
    mean = cmp["phase_offset"]["mean"]
    if mean is not None and abs(mean) > opts.phase_tol:
        names.append("phase_offset")
    return sorted(names)


def gamma_differs(a: float | None, b: float | None, tol: float) -> bool:
    """True when only one Gamma is given or they differ by more than ``tol``."""
    if a is None or b is None:
        return (a is None) != (b is None)
    return abs(float(a) - float(b)) > tol + 1e-9


def plateaus_differ(a: list[dict], b: list[dict], tol: float) -> bool:
    """True when two plateau lists differ in their orders or in an edge by > ``tol``."""
    if [p["n"] for p in a] != [p["n"] for p in b]:
        return True
    return any(
        gamma_differs(pa[edge], pb[edge], tol)
        for pa, pb in zip(a, b, strict=True)
        for edge in ("gamma_min", "gamma_max")
    )
