"""Distances between measured and simulated flights, per Gamma step.

Two distances per step, both in radians of drive phase (the unit of ``T``):

``w1_T``
    the 1-D Wasserstein-1 distance between the two samples of flight times ``T``: the
    mean distance by which flight times must be moved to turn one sample into the other
    (a shift of every flight by ``d`` gives ``d``).
``w_returnmap``
    a sliced Wasserstein-1 distance between the return-map samples ``(T_n, T_n+1)``
    (pairs of flights that follow each other in time, both settled), averaged over a
    fixed set of projection directions and scaled so that a shift of every flight by
    ``d`` again gives ``d``. It sees what ``w1_T`` cannot: the order of the flights
    (a period-2 orbit against a random mixture of the same two flight times).

A side with no flights in a step (the body stuck on the plate) while the other side has
flights is compared with a point mass at ``T = 0`` (return map: at the origin): a body
that never leaves has flight time zero. The distance is then the mean flight time of the
other side, large against the sampling noise but finite. Both sides empty: distance 0.

Speed: :func:`prepare_flights` sorts a table once (keyed by step, then value); the
distance of two prepared samples then only merges sorted runs, in linear time (a small
numba kernel). One full comparison of a 100-step run with 10^4 flights per side
takes a few milliseconds (``benchmarks/bench_gap.py``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from bouncelab.errors import BouncelabError
from bouncelab.gap._kernels import w1_by_step as w1_kernel

#: Offset between steps in the sort key ``step * KEY_SPAN + value``. A power of two keeps
#: ``step * KEY_SPAN`` exact; values (flight times and their projections, radians) must lie
#: in ``(-KEY_SPAN / 2, KEY_SPAN / 2)``, far beyond any flight of the rig (T < ~50 rad).
KEY_SPAN = 1024.0

#: Number of projection directions of the sliced return-map distance.
DEFAULT_DIRECTIONS = 4

#: Weight of ``w1_T`` in the per-step ``gap``; ``w_returnmap`` gets ``1 - DEFAULT_ALPHA``.
DEFAULT_ALPHA = 0.5

#: Columns that name a time within a step, tried in this order to put flights in order.
TIME_COLUMNS = ("t_takeoff_s", "t_takeoff")

GAP_COLUMNS = ("step", "gamma", "n_data", "n_sim", "w1_T", "w_returnmap", "gap")


def projection_directions(n_directions: int = DEFAULT_DIRECTIONS) -> np.ndarray:
    """Fixed unit vectors for the sliced return-map distance.

    Angles ``pi (k + 1/2) / n`` for ``k = 0..n-1``: evenly spread over a half turn
    (a direction and its opposite give the same distance) and never on an axis, since
    the axes only repeat the flight-time marginal that ``w1_T`` already measures.

    Returns
    -------
    ndarray, shape (n_directions, 2)
        ``(cos, sin)`` of each angle; deterministic, no random numbers.
    """
    if n_directions < 1:
        raise ValueError("n_directions must be at least 1")
    angles = np.pi * (np.arange(n_directions) + 0.5) / n_directions
    return np.column_stack([np.cos(angles), np.sin(angles)])


def returnmap_scale(directions: np.ndarray) -> float:
    """Factor that makes the sliced distance of a uniform flight-time shift equal the shift.

    A shift of every ``T`` by ``d`` moves the pair ``(T_n, T_n+1)`` by ``(d, d)``, whose
    projection on ``(c, s)`` is ``d (c + s)``; the mean over directions of ``|c + s|`` is
    divided out. Dimensionless.
    """
    return float(1.0 / np.mean(np.abs(directions[:, 0] + directions[:, 1])))


@dataclass(frozen=True)
class SortedValues:
    """One sample of values per step, sorted by ``(step, value)``.

    Attributes (all 1-D, the same length ``n``)
    ----------
    value : float64, radians, ascending within each step
    step : int64, step index of each value, ascending
    """

    value: np.ndarray
    step: np.ndarray


@dataclass(frozen=True)
class FlightSample:
    """A flight table prepared for repeated distance computations.

    Attributes
    ----------
    flights : SortedValues
        settled flight times ``T`` (rad), one per flight.
    projections : tuple of SortedValues
        for each of ``directions``, the projections of the return-map pairs (rad).
    directions : ndarray, shape (K, 2)
        the projection directions used.
    steps : ndarray of int64, shape (S,)
        the steps present in the table (any flight, settled or not), ascending.
    gammas : ndarray of float64, shape (S,)
        the Gamma of each of ``steps`` (first row of that step).
    """

    flights: SortedValues
    projections: tuple[SortedValues, ...]
    directions: np.ndarray
    steps: np.ndarray
    gammas: np.ndarray


def _sorted_values(step: np.ndarray, value: np.ndarray) -> SortedValues:
    # One float sort key instead of a two-key lexsort (twice as fast); values that differ
    # by less than the key's rounding (~1e-10 rad) may swap, which changes no distance
    # by more than that.
    key = step.astype(np.float64) * KEY_SPAN + value
    order = np.argsort(key, kind="stable")
    return SortedValues(
        np.ascontiguousarray(value[order], dtype=np.float64),
        np.ascontiguousarray(step[order], dtype=np.int64),
    )


def _check_table(table: pd.DataFrame, name: str) -> None:
    if not isinstance(table, pd.DataFrame):
        raise BouncelabError(None, f"{name} flight table must be a DataFrame, not {type(table)}")
    for col in ("step", "gamma", "T"):
        if col not in table.columns:
            raise BouncelabError(None, f"{name} flight table lacks column {col!r}")
    if "run" in table.columns and table["run"].nunique() > 1:
        raise BouncelabError(
            None, f"{name} flight table holds {table['run'].nunique()} runs; compare one at a time"
        )


def flight_order(table: pd.DataFrame) -> np.ndarray:
    """Row order that puts flights in time within each ensemble member.

    Sorted by ``start`` (when present), then by the first of :data:`TIME_COLUMNS` that
    the table has; without a time column the row order is taken as the time order.

    Returns
    -------
    ndarray of int64, shape (n_rows,)
    """
    n = len(table)
    time_col = next((c for c in TIME_COLUMNS if c in table.columns), None)
    if time_col is not None:
        time = table[time_col].to_numpy(dtype=np.float64)
    else:
        time = np.arange(n, dtype=np.float64)
    if "start" not in table.columns:
        if np.all(np.diff(time) >= 0):
            return np.arange(n)  # already in time order: the common case, no sort
        return np.argsort(time, kind="stable")
    start = table["start"].to_numpy(dtype=np.int64)
    ds, dt = np.diff(start), np.diff(time)
    if np.all((ds > 0) | ((ds == 0) & (dt >= 0))):
        return np.arange(n)
    return np.lexsort((time, start))


def return_map_pairs(
    table: pd.DataFrame,
    *,
    settled_only: bool = True,
    segment: np.ndarray | None = None,
    name: str = "flights",
) -> pd.DataFrame:
    """Consecutive flight pairs ``(T_n, T_n+1)`` within each step.

    A pair is two flights that follow each other in time (see :func:`flight_order`), in
    the same step, the same ensemble member (``start``) and the same ``segment`` (an
    optional integer label per row, used to keep pairs inside the blocks of a split
    sample), both settled when ``settled_only``.

    Returns
    -------
    DataFrame with columns ``step`` (int), ``T_n``, ``T_next`` (rad); one row per pair.
    """
    _check_table(table, name)
    step, x, y = _pairs(table, settled_only=settled_only, segment=segment, name=name)
    return pd.DataFrame({"step": step, "T_n": x, "T_next": y})


def _flight_arrays(table: pd.DataFrame, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    step = table["step"].to_numpy(dtype=np.int64)
    t = table["T"].to_numpy(dtype=np.float64)
    if not np.all(np.isfinite(t)) or np.any(t < 0):
        bad = int(np.sum(~np.isfinite(t) | (t < 0)))
        raise BouncelabError(
            None, f"{name} flight table has {bad} flight times T that are not >= 0"
        )
    if np.any(t >= KEY_SPAN / 2) or np.any(step < 0):
        raise BouncelabError(None, f"{name} flight table has negative steps or T >= {KEY_SPAN / 2}")
    if "settled" in table.columns:
        settled = table["settled"].to_numpy(dtype=bool)
    else:
        settled = np.ones(len(table), dtype=bool)
    return step, t, settled


def _pairs(
    table: pd.DataFrame, *, settled_only: bool, segment: np.ndarray | None, name: str
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    step, t, settled = _flight_arrays(table, name)
    return _pairs_from_arrays(table, step, t, settled, settled_only, segment)


def _pairs_from_arrays(
    table: pd.DataFrame,
    step: np.ndarray,
    t: np.ndarray,
    settled: np.ndarray,
    settled_only: bool,
    segment: np.ndarray | None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Steps, ``T_n`` and ``T_n+1`` of consecutive pairs; arrays in table row order."""
    order = flight_order(table)
    step, t, settled = step[order], t[order], settled[order]
    same = step[1:] == step[:-1]
    if "start" in table.columns:
        start = table["start"].to_numpy(dtype=np.int64)[order]
        same &= start[1:] == start[:-1]
    if segment is not None:
        seg = np.asarray(segment)[order]
        same &= seg[1:] == seg[:-1]
    if settled_only:
        same &= settled[1:] & settled[:-1]
    i = np.flatnonzero(same)
    return step[i], t[i], t[i + 1]


def prepare_flights(
    table: pd.DataFrame | FlightSample,
    *,
    settled_only: bool = True,
    n_directions: int = DEFAULT_DIRECTIONS,
    segment: np.ndarray | None = None,
    name: str = "flights",
) -> FlightSample:
    """Sort a flight table once for many distance computations.

    Parameters
    ----------
    table : DataFrame
        flight table (CONTRACTS.md section 3 or a simulation): columns ``step``,
        ``gamma``, ``T`` (rad), optional ``settled``, ``start``, a time column. An
        already prepared :class:`FlightSample` is returned as is.
    settled_only : bool
        keep only settled flights (the lab discards the first cycles of each step).
    n_directions : int
        projection directions of the sliced return-map distance.
    segment : ndarray of int, shape (n_rows,), optional
        pairs are formed only between rows of the same segment.
    name : str
        how error messages name the table (``"data"``, ``"simulation"``).

    Raises
    ------
    BouncelabError
        missing columns, several runs in one table, flight times not finite or negative.
    """
    if isinstance(table, FlightSample):
        return table
    _check_table(table, name)
    step, t, settled = _flight_arrays(table, name)
    keep = settled if settled_only else np.ones_like(settled)
    flights = _sorted_values(step[keep], t[keep])

    directions = projection_directions(n_directions)
    p_step, x, y = _pairs_from_arrays(table, step, t, settled, settled_only, segment)
    projections = tuple(_sorted_values(p_step, x * c + y * s) for c, s in directions)

    steps, first = np.unique(step, return_index=True)
    gammas = table["gamma"].to_numpy(dtype=np.float64)[first]
    return FlightSample(flights, projections, directions, steps, gammas)


def _w1_by_step(
    a: SortedValues, b: SortedValues, grid: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Wasserstein-1 distance per step between two step-sorted samples.

    Exact for empirical distributions of any sizes: the integral over the value axis of
    ``|F_a - F_b|`` (a linear merge in :func:`bouncelab.gap._kernels.w1_by_step`). A step
    where one side is empty and the other is not uses a point mass at 0 for the empty side.

    Parameters
    ----------
    a, b : SortedValues
    grid : ndarray of int64, shape (G,), ascending step indices to report.

    Returns
    -------
    (w, n_a, n_b): ndarray shape (G,) in radians, and the counts per step of each side.
    """
    return w1_kernel(grid, a.step, a.value, b.step, b.value)


def step_distances(a: FlightSample, b: FlightSample, grid: np.ndarray) -> dict[str, np.ndarray]:
    """Both distances and the sample sizes per step of ``grid``.

    Parameters
    ----------
    a, b : FlightSample
        prepared with the same projection directions.
    grid : ndarray of int64, shape (G,), ascending step indices.

    Returns
    -------
    dict of ndarray, each shape (G,):
        ``w1_T``, ``w_returnmap`` (rad), ``n_a``, ``n_b`` (settled flights),
        ``pairs_a``, ``pairs_b`` (return-map pairs).
    """
    if a.directions.shape != b.directions.shape or not np.allclose(a.directions, b.directions):
        raise ValueError("the two samples were prepared with different projection directions")
    grid = np.ascontiguousarray(grid, dtype=np.int64)
    w1, n_a, n_b = _w1_by_step(a.flights, b.flights, grid)
    sliced = np.zeros(len(grid))
    pairs_a = pairs_b = np.zeros(len(grid), dtype=np.int64)
    for pa, pb in zip(a.projections, b.projections, strict=True):
        w, pairs_a, pairs_b = _w1_by_step(pa, pb, grid)
        sliced += w
    sliced *= returnmap_scale(a.directions) / max(len(a.projections), 1)
    return {
        "w1_T": w1,
        "w_returnmap": sliced,
        "n_a": n_a,
        "n_b": n_b,
        "pairs_a": pairs_a,
        "pairs_b": pairs_b,
    }


def wasserstein_1d(a: np.ndarray, b: np.ndarray) -> float:
    """Wasserstein-1 distance between two samples of flight times (rad).

    Parameters
    ----------
    a, b : array_like, shape (n,) and (m,)
        flight times, radians; an empty sample stands for a body stuck on the plate
        (a point mass at 0).

    Returns
    -------
    float, radians; 0 when both are empty.
    """
    a = np.asarray(a, dtype=np.float64).ravel()
    b = np.asarray(b, dtype=np.float64).ravel()
    grid = np.zeros(1, dtype=np.int64)
    sa = _sorted_values(np.zeros(len(a), dtype=np.int64), a)
    sb = _sorted_values(np.zeros(len(b), dtype=np.int64), b)
    return float(_w1_by_step(sa, sb, grid)[0][0])


def sliced_wasserstein_2d(
    p: np.ndarray, q: np.ndarray, n_directions: int = DEFAULT_DIRECTIONS
) -> float:
    """Sliced Wasserstein-1 distance between two return-map samples (rad).

    The mean over :func:`projection_directions` of the 1-D Wasserstein-1 distance of the
    projected points, times :func:`returnmap_scale` so that shifting every coordinate
    by ``d`` gives ``d``.

    Parameters
    ----------
    p, q : array_like, shape (n, 2) and (m, 2)
        points ``(T_n, T_n+1)``, radians; an empty sample is a point mass at the origin.
    """
    p = np.asarray(p, dtype=np.float64).reshape(-1, 2)
    q = np.asarray(q, dtype=np.float64).reshape(-1, 2)
    dirs = projection_directions(n_directions)
    total = sum(wasserstein_1d(p @ d, q @ d) for d in dirs)
    return float(total * returnmap_scale(dirs) / len(dirs))


def table_steps(table: pd.DataFrame | FlightSample) -> tuple[np.ndarray, np.ndarray]:
    """Steps present in a flight table (any flight) and the Gamma of each (first row).

    Returns
    -------
    (steps, gammas): ndarray of int64 and float64, shape (S,), ascending steps.
    """
    if isinstance(table, FlightSample):
        return table.steps, table.gammas
    steps, first = np.unique(table["step"].to_numpy(dtype=np.int64), return_index=True)
    return steps, table["gamma"].to_numpy(dtype=np.float64)[first]


def step_grid(
    *samples: FlightSample | pd.DataFrame, steps: pd.DataFrame | np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """The steps to compare and their Gamma.

    Parameters
    ----------
    samples : FlightSample or DataFrame
        their steps are joined when ``steps`` is not given; the first sample that has a
        step gives its Gamma.
    steps : DataFrame with ``step`` and ``gamma`` columns (e.g. ``runs.step_table``), or
        an array of step indices, optional. Give it to count steps where both sides
        stay on the plate (no rows in either table); those have gap 0.

    Returns
    -------
    (steps, gammas): ndarray of int64 and float64, shape (G,), ascending steps; gamma NaN
    where no source names it.
    """
    if isinstance(steps, pd.DataFrame):
        grid = steps["step"].to_numpy(dtype=np.int64)
        order = np.argsort(grid, kind="stable")
        return grid[order], steps["gamma"].to_numpy(dtype=np.float64)[order]
    known = [table_steps(s) for s in samples]
    if steps is not None:
        grid = np.unique(np.asarray(steps, dtype=np.int64))
    else:
        grid = np.unique(np.concatenate([k[0] for k in known] or [np.zeros(0, np.int64)]))
    gammas = np.full(len(grid), np.nan)
    for s_steps, s_gammas in reversed(known):  # the first sample wins: overwrite in reverse
        code = np.minimum(np.searchsorted(grid, s_steps), max(len(grid) - 1, 0))
        inside = grid[code] == s_steps if len(grid) else np.zeros(len(s_steps), dtype=bool)
        gammas[code[inside]] = s_gammas[inside]
    return grid, gammas


def gap_table(
    data: pd.DataFrame | FlightSample,
    sim: pd.DataFrame | FlightSample,
    *,
    steps: pd.DataFrame | np.ndarray | None = None,
    alpha: float = DEFAULT_ALPHA,
    settled_only: bool = True,
    n_directions: int = DEFAULT_DIRECTIONS,
) -> pd.DataFrame:
    """Per-step gap between measured and simulated flights.

    Parameters
    ----------
    data, sim : DataFrame or FlightSample
        flight tables with ``step``, ``gamma``, ``T``; optional ``settled``, ``start``,
        time column. Prepare ``data`` once with :func:`prepare_flights` when comparing it
        with many simulations.
    steps : see :func:`step_grid`.
    alpha : float in [0, 1]
        ``gap = alpha * w1_T + (1 - alpha) * w_returnmap``.

    Returns
    -------
    DataFrame, one row per step, columns :data:`GAP_COLUMNS`:
    ``step``, ``gamma``, ``n_data``, ``n_sim`` (settled flights), ``w1_T``,
    ``w_returnmap``, ``gap`` (rad); plus ``pairs_data``, ``pairs_sim``.
    """
    if not 0.0 <= alpha <= 1.0:
        raise ValueError("alpha must lie in [0, 1]")
    kw = {"settled_only": settled_only, "n_directions": n_directions}
    a = prepare_flights(data, name="data", **kw)
    b = prepare_flights(sim, name="simulation", **kw)
    grid, gammas = step_grid(a, b, steps=steps)
    d = step_distances(a, b, grid)
    return pd.DataFrame(
        {
            "step": grid,
            "gamma": gammas,
            "n_data": d["n_a"],
            "n_sim": d["n_b"],
            "w1_T": d["w1_T"],
            "w_returnmap": d["w_returnmap"],
            "gap": alpha * d["w1_T"] + (1.0 - alpha) * d["w_returnmap"],
            "pairs_data": d["pairs_a"],
            "pairs_sim": d["pairs_b"],
        }
    )


def step_weights(table: pd.DataFrame, weights: str = "equal") -> np.ndarray:
    """Weights of the steps in an overall mean.

    ``"equal"``: every Gamma step counts the same (default). Gamma is the control
    variable; weighting by flights would let the many short flights of low Gamma
    outweigh the few long ones of high Gamma.
    ``"gamma"``: the width in Gamma each step stands for (half the distance to each
    neighbour in Gamma), so that an uneven grid gives the mean over Gamma.

    Returns
    -------
    ndarray, shape (n_rows,), summing to 1 (all equal for a single step).
    """
    n = len(table)
    if n == 0:
        return np.zeros(0)
    if weights == "equal":
        w = np.ones(n)
    elif weights == "gamma":
        g = table["gamma"].to_numpy(dtype=np.float64)
        order = np.argsort(g, kind="stable")
        gs = g[order]
        edges = np.concatenate([[gs[0]], 0.5 * (gs[1:] + gs[:-1]), [gs[-1]]])
        w = np.empty(n)
        w[order] = np.diff(edges)
        if not np.all(np.isfinite(w)) or w.sum() <= 0:
            w = np.ones(n)
    else:
        raise ValueError(f"weights must be 'equal' or 'gamma', not {weights!r}")
    return w / w.sum()


def overall_gap(table: pd.DataFrame, column: str = "gap", weights: str = "equal") -> float:
    """Weighted mean over steps of one column of a gap table (rad for ``gap``).

    Steps where the column is NaN are left out. See :func:`step_weights` for
    ``weights``. Returns NaN for an empty table.
    """
    values = table[column].to_numpy(dtype=np.float64)
    ok = np.isfinite(values)
    if not ok.any():
        return float("nan")
    w = step_weights(table.loc[ok], weights)
    return float(np.sum(w * values[ok]))
