"""The noise floor: the gap that finite samples give when nothing differs.

A distance between two finite samples of the same process is not zero. As in the
misspecification tests of simulation-based inference (compare the real-vs-simulated
distance with the spread of simulated-vs-simulated distances), every gap is stated
relative to this floor.

Per step and for each distance, a *noise scale* ``s`` (rad x sqrt(flights)) is measured
by splitting a sample into two halves that come from the same process:

``s = d(half_a, half_b) / sqrt(1/h_a + 1/h_b)``

where ``h_a, h_b`` are the halves' sizes (flights for ``w1_T``, pairs for the return
map). The Wasserstein-1 distance between two samples of one distribution shrinks like
``sqrt(1/n + 1/m)``, so the floor of a comparison of ``n_data`` measured with ``n_sim``
simulated flights is

``floor = sqrt(s_data^2 / n_data + s_sim^2 / n_sim)``

(each sample contributes its own spread: a chaotic measured step against a periodic
model is noisy on the data side only). The floor of ``gap`` is the same mix
``alpha * floor_w1_T + (1 - alpha) * floor_w_returnmap`` as the gap.

Halves of the data: by default the first and the second half in time of each step's
settled flights. Consecutive flights are correlated (periodic orbits, slow transients
near a flip, intermittency), and two halves of one correlated sequence are closer than
two independent samples: splitting by single flights (odd against even) would even put
the short and the long flights of a period-2 orbit into different halves. On correlated
synthetic sequences (AR(1), 50-200 flights per step) the first/second split gave
``gap / floor`` of 0.96-1.4 against 1.6-4.9 for interleaved blocks of 8 flights; a slow
drift within a step counts as noise this way, which errs on the side of no false alarm.
Interleaved blocks (``block=k``: blocks of ``k`` flights alternately to each half) are
an option for long stationary steps. Halves of a simulation: other ensemble
members (even against odd ``start``), or a second simulation with another seed.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from bouncelab.gap.distances import (
    DEFAULT_ALPHA,
    DEFAULT_DIRECTIONS,
    FlightSample,
    flight_order,
    gap_table,
    overall_gap,
    prepare_flights,
    step_distances,
    step_grid,
)

#: Block length (flights) of the data split; None: first against second half in time.
DEFAULT_BLOCK = None

#: Smallest floor used in ``rel_gap`` (rad): about one sample of timing resolution of
#: the rig (20 kHz at a 30-40 Hz drive is 0.009-0.013 rad). Exactly periodic samples
#: have a floor of 0, which would make any gap infinitely significant.
DEFAULT_MIN_FLOOR = 0.01

SCALE_COLUMNS = ("s_data_T", "s_data_rm", "s_sim_T", "s_sim_rm")


def block_labels(
    table: pd.DataFrame, block: int | None = DEFAULT_BLOCK, settled_only: bool = True
) -> np.ndarray:
    """Block index of each row: ``rank // block`` among its step's flights in time order.

    The rank counts flights (settled ones when ``settled_only``) of the same step and
    ensemble member (``start``) in time order (:func:`flight_order`). ``block=None``
    cuts each step into its first and second half in time (labels 0 and 1).

    Returns
    -------
    ndarray of int64, shape (n_rows,); -1 for rows left out (not settled).
    """
    if block is not None and block < 1:
        raise ValueError("block must be at least 1")
    n = len(table)
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    order = flight_order(table)
    step = table["step"].to_numpy(dtype=np.int64)[order]
    if "start" in table.columns:
        # (start, step) pairs: a new group wherever either changes
        start = table["start"].to_numpy(dtype=np.int64)[order]
        new = np.concatenate([[True], (step[1:] != step[:-1]) | (start[1:] != start[:-1])])
    else:
        new = np.concatenate([[True], step[1:] != step[:-1]])
    keep = np.ones(n, dtype=bool)
    if settled_only and "settled" in table.columns:
        keep = table["settled"].to_numpy(dtype=bool)[order]
    # rank among kept rows of the same group: kept rows so far minus those before the group
    kept_cum = np.cumsum(keep)
    group_id = np.cumsum(new) - 1
    first = np.flatnonzero(new)
    kept_before = (kept_cum - keep)[first]
    rank = kept_cum - 1 - kept_before[group_id]
    if block is None:
        # first against second half of each group: block = ceil(n_group / 2)
        n_group = np.bincount(group_id, weights=keep)[group_id]
        size = np.maximum(np.ceil(n_group / 2.0), 1.0).astype(np.int64)
    else:
        size = block
    labels_sorted = np.where(keep, rank // size, -1)
    labels = np.empty(n, dtype=np.int64)
    labels[order] = labels_sorted
    return labels


def split_halves(
    table: pd.DataFrame,
    *,
    block: int | None = DEFAULT_BLOCK,
    settled_only: bool = True,
    n_directions: int = DEFAULT_DIRECTIONS,
    name: str = "data",
) -> tuple[FlightSample, FlightSample]:
    """Two halves of one flight table from interleaved blocks, prepared for distances.

    Even blocks (:func:`block_labels`) go to the first half, odd ones to the second;
    return-map pairs stay inside a block, so no pair joins flights that are not
    consecutive in time.
    """
    labels = block_labels(table, block, settled_only)
    halves = []
    for parity in (0, 1):
        mask = (labels >= 0) & (labels % 2 == parity)
        halves.append(
            prepare_flights(
                table.loc[mask],
                settled_only=settled_only,
                n_directions=n_directions,
                segment=labels[mask],
                name=name,
            )
        )
    return halves[0], halves[1]


def split_starts(
    table: pd.DataFrame, *, settled_only: bool = True, n_directions: int = DEFAULT_DIRECTIONS
) -> tuple[FlightSample, FlightSample]:
    """Two halves of a simulation from its ensemble members: even against odd ``start``."""
    starts = table["start"].to_numpy(dtype=np.int64)
    rank = np.searchsorted(np.unique(starts), starts)
    kw = {"settled_only": settled_only, "n_directions": n_directions, "name": "simulation"}
    return (
        prepare_flights(table.loc[rank % 2 == 0], **kw),
        prepare_flights(table.loc[rank % 2 == 1], **kw),
    )


def noise_scale(distance: np.ndarray, n_a: np.ndarray, n_b: np.ndarray) -> np.ndarray:
    """Per-step noise scale ``s = d / sqrt(1/n_a + 1/n_b)`` (rad x sqrt(count)).

    Both halves empty: 0 (nothing moves, no noise). One half empty: NaN (a split that
    cannot tell noise from sticking; filled later, see :func:`fill_scales`).

    Parameters
    ----------
    distance : ndarray, shape (G,), rad
    n_a, n_b : ndarray, shape (G,), sizes of the halves
    """
    n_a = np.asarray(n_a, dtype=np.float64)
    n_b = np.asarray(n_b, dtype=np.float64)
    s = np.full(len(distance), np.nan)
    both = (n_a > 0) & (n_b > 0)
    s[both] = distance[both] / np.sqrt(1.0 / n_a[both] + 1.0 / n_b[both])
    s[(n_a == 0) & (n_b == 0)] = 0.0
    return s


def fill_scales(primary: np.ndarray, fallback: np.ndarray) -> np.ndarray:
    """Fill NaN scales from ``fallback`` (the other side), then with the median over steps.

    The median of the finite values stands in for a step whose split says nothing; 0 when
    no step has a finite value. Shape (G,) in and out.
    """
    s = np.where(np.isfinite(primary), primary, fallback)
    finite = np.isfinite(s)
    return np.where(finite, s, np.median(s[finite]) if finite.any() else 0.0)


def floor_from_scales(s_a: np.ndarray, n_a: np.ndarray, s_b: np.ndarray, n_b: np.ndarray):
    """Floor of one distance for samples of sizes ``n_a``, ``n_b``: ``sqrt(s_a^2/n_a + s_b^2/n_b)``.

    A side with no flights adds nothing (its term is 0). All arrays shape (G,); rad.
    """
    n_a = np.asarray(n_a, dtype=np.float64)
    n_b = np.asarray(n_b, dtype=np.float64)
    term_a = np.divide(s_a**2, n_a, out=np.zeros(len(n_a)), where=n_a > 0)
    term_b = np.divide(s_b**2, n_b, out=np.zeros(len(n_b)), where=n_b > 0)
    return np.sqrt(term_a + term_b)


def _scales(a: FlightSample, b: FlightSample, grid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    d = step_distances(a, b, grid)
    return (
        noise_scale(d["w1_T"], d["n_a"], d["n_b"]),
        noise_scale(d["w_returnmap"], d["pairs_a"], d["pairs_b"]),
    )


def noise_floor(
    data: pd.DataFrame,
    sim: pd.DataFrame | None = None,
    *,
    sim_alt: pd.DataFrame | None = None,
    steps: pd.DataFrame | np.ndarray | None = None,
    block: int | None = DEFAULT_BLOCK,
    alpha: float = DEFAULT_ALPHA,
    settled_only: bool = True,
    n_directions: int = DEFAULT_DIRECTIONS,
) -> pd.DataFrame:
    """Per-step noise floor of the comparison of ``data`` with ``sim``.

    Parameters
    ----------
    data : DataFrame
        measured flights (CONTRACTS.md section 3).
    sim : DataFrame, optional
        simulated flights. Its noise scale comes from ``sim_alt`` (the same model with
        another seed) when given, else from its ensemble members (even against odd
        ``start``) when it has two or more, else from block halves like the data.
        Without ``sim``, the floor is that of the data against a second sample of the
        same size and spread: ``n_sim = n_data``, ``s_sim = s_data``.
    steps : see :func:`bouncelab.gap.distances.step_grid`.
    block : int or None
        block length of the data split (flights), see the module docstring; None cuts
        each step into first and second half in time.
    alpha : float
        weight of ``w1_T`` in ``gap`` (the same as in ``gap_table``).

    Returns
    -------
    DataFrame, one row per step: ``step``, ``gamma``, ``n_data``, ``n_sim``,
    ``pairs_data``, ``pairs_sim``, the noise scales ``s_data_T``, ``s_data_rm``,
    ``s_sim_T``, ``s_sim_rm`` (rad x sqrt(count); NaN filled, see :func:`fill_scales`),
    and ``floor_w1_T``, ``floor_w_returnmap``, ``floor`` (rad).
    """
    kw = {"settled_only": settled_only, "n_directions": n_directions}
    full_data = prepare_flights(data, name="data", **kw)
    full_sim = prepare_flights(sim, name="simulation", **kw) if sim is not None else None
    samples = (full_data,) if full_sim is None else (full_data, full_sim)
    grid, gammas = step_grid(*samples, steps=steps)

    da, db = split_halves(data, block=block, name="data", **kw)
    s_data_T, s_data_rm = _scales(da, db, grid)
    count = step_distances(full_data, full_data, grid)
    n_data, pairs_data = count["n_a"], count["pairs_a"]

    if full_sim is None:
        s_sim_T, s_sim_rm = s_data_T, s_data_rm
        n_sim, pairs_sim = n_data, pairs_data
    else:
        if sim_alt is not None:
            sa, sb = full_sim, prepare_flights(sim_alt, name="simulation", **kw)
        elif "start" in sim.columns and sim["start"].nunique() >= 2:
            sa, sb = split_starts(sim, **kw)
        else:
            sa, sb = split_halves(sim, block=block, name="simulation", **kw)
        s_sim_T, s_sim_rm = _scales(sa, sb, grid)
        count = step_distances(full_sim, full_sim, grid)
        n_sim, pairs_sim = count["n_a"], count["pairs_a"]

    table = pd.DataFrame(
        {
            "step": grid,
            "gamma": gammas,
            "n_data": n_data,
            "n_sim": n_sim,
            "pairs_data": pairs_data,
            "pairs_sim": pairs_sim,
            "s_data_T": fill_scales(s_data_T, s_sim_T),
            "s_data_rm": fill_scales(s_data_rm, s_sim_rm),
            "s_sim_T": fill_scales(s_sim_T, s_data_T),
            "s_sim_rm": fill_scales(s_sim_rm, s_data_rm),
        }
    )
    return _with_floor_columns(table, alpha)


def _floor_columns(cols: dict, alpha: float) -> dict:
    """Floor columns (rad) from the scale and count columns of ``cols`` (arrays)."""
    f_t = floor_from_scales(cols["s_data_T"], cols["n_data"], cols["s_sim_T"], cols["n_sim"])
    f_rm = floor_from_scales(
        cols["s_data_rm"], cols["pairs_data"], cols["s_sim_rm"], cols["pairs_sim"]
    )
    return {
        "floor_w1_T": f_t,
        "floor_w_returnmap": f_rm,
        "floor": alpha * f_t + (1.0 - alpha) * f_rm,
    }


def _with_floor_columns(table: pd.DataFrame, alpha: float) -> pd.DataFrame:
    cols = {c: table[c].to_numpy() for c in table.columns}
    cols.update(_floor_columns(cols, alpha))
    return pd.DataFrame(cols)


def relative_gap(
    gaps: pd.DataFrame,
    floor: pd.DataFrame,
    *,
    alpha: float = DEFAULT_ALPHA,
    min_floor: float = DEFAULT_MIN_FLOOR,
) -> pd.DataFrame:
    """The gap table with its noise floor and the gap relative to it.

    The floor is recomputed for the sample sizes of ``gaps`` from the noise scales of
    ``floor`` (so a floor measured once serves every simulation of a fit). Steps of
    ``gaps`` missing from ``floor`` get the median scales.

    Parameters
    ----------
    gaps : DataFrame from :func:`bouncelab.gap.distances.gap_table`.
    floor : DataFrame from :func:`noise_floor`.
    alpha : float
        the ``alpha`` the gap table was made with.
    min_floor : float, rad
        ``rel_gap = gap / max(floor, min_floor)``, see :data:`DEFAULT_MIN_FLOOR`.

    Returns
    -------
    Copy of ``gaps`` with the scale columns and ``floor_w1_T``, ``floor_w_returnmap``,
    ``floor``, ``floor_used = max(floor, min_floor)`` (rad) and ``rel_gap = gap /
    floor_used`` (dimensionless; about 1 when the model matches).
    """
    # numpy rather than a DataFrame merge: this runs once per evaluation of a fit
    cols = {c: gaps[c].to_numpy() for c in gaps.columns}
    step = cols["step"].astype(np.int64)
    f_step = floor["step"].to_numpy(dtype=np.int64)
    order = np.argsort(f_step, kind="stable")
    f_step = f_step[order]
    pos = np.minimum(np.searchsorted(f_step, step), max(len(f_step) - 1, 0))
    found = f_step[pos] == step if len(f_step) else np.zeros(len(step), dtype=bool)
    for col in SCALE_COLUMNS:
        values = floor[col].to_numpy(dtype=np.float64)[order]
        mapped = np.where(found, values[pos] if len(values) else np.nan, np.nan)
        cols[col] = fill_scales(mapped, np.full(len(step), np.nan))
    cols.update(_floor_columns(cols, alpha))
    cols["floor_used"] = np.maximum(cols["floor"], min_floor)
    cols["rel_gap"] = cols["gap"] / cols["floor_used"]
    return pd.DataFrame(cols)


def overall_relative_gap(table: pd.DataFrame, weights: str = "equal") -> float:
    """Overall gap divided by the overall floor (both weighted means over steps).

    A ratio of means rather than a mean of ratios: steps with a tiny floor do not
    dominate. Uses ``floor_used`` when the table has it (see :func:`relative_gap`).
    About 1 when the model matches the data; NaN when the floor is 0.
    """
    column = "floor_used" if "floor_used" in table.columns else "floor"
    floor = overall_gap(table, column, weights)
    if not floor > 0:
        return float("nan")
    return overall_gap(table, "gap", weights) / floor


def null_relative_gaps(
    replicates: list[pd.DataFrame],
    *,
    steps: pd.DataFrame | np.ndarray | None = None,
    block: int | None = DEFAULT_BLOCK,
    alpha: float = DEFAULT_ALPHA,
    min_floor: float = DEFAULT_MIN_FLOOR,
    weights: str = "equal",
) -> np.ndarray:
    """The sbi-style null distribution: ``overall_relative_gap`` of simulation against
    simulation.

    Each replicate (the same model, another seed; shaped like the data, e.g. one
    ensemble member with the data's timing noise) plays the data against the next one
    (cyclically) as the model, with the floor measured exactly as for real data. A real
    ``overall_relative_gap`` well above this spread means the model misses something.

    Parameters
    ----------
    replicates : list of at least 2 flight tables.

    Returns
    -------
    ndarray, shape (len(replicates),), dimensionless.
    """
    if len(replicates) < 2:
        raise ValueError("need at least two replicates")
    out = np.empty(len(replicates))
    for i, data in enumerate(replicates):
        sim = replicates[(i + 1) % len(replicates)]
        floor = noise_floor(data, sim, steps=steps, block=block, alpha=alpha)
        gaps = gap_table(data, sim, steps=steps, alpha=alpha)
        out[i] = overall_relative_gap(
            relative_gap(gaps, floor, alpha=alpha, min_floor=min_floor), weights
        )
    return out
