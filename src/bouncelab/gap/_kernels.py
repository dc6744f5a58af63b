"""Numba kernel of the per-step Wasserstein-1 distance (the inner loop of every fit).

Kept apart from the Python that prepares its inputs (DESIGN.md section 5).
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, nogil=True)
def w1_by_step(grid, a_step, a_val, b_step, b_val):  # pragma: no cover - compiled
    """Wasserstein-1 distance per step of two samples sorted by ``(step, value)``.

    Walks both samples once (a merge of sorted runs), integrating ``|F_a - F_b|``
    between consecutive values. Elements whose step is not in ``grid`` are skipped.
    A step where one side has no values compares the other side with a point mass at 0
    (mean absolute value); both sides empty give 0.

    Parameters
    ----------
    grid : int64[G], ascending step indices
    a_step, b_step : int64[n], int64[m], ascending
    a_val, b_val : float64[n], float64[m], ascending within each step

    Returns
    -------
    (w, na, nb): float64[G] distance (units of the values), int64[G] counts per side.
    """
    n_groups = grid.shape[0]
    w = np.zeros(n_groups)
    na_out = np.zeros(n_groups, dtype=np.int64)
    nb_out = np.zeros(n_groups, dtype=np.int64)
    i = 0
    j = 0
    na_all = a_step.shape[0]
    nb_all = b_step.shape[0]
    for g in range(n_groups):
        s = grid[g]
        while i < na_all and a_step[i] < s:
            i += 1
        while j < nb_all and b_step[j] < s:
            j += 1
        i0 = i
        j0 = j
        while i < na_all and a_step[i] == s:
            i += 1
        while j < nb_all and b_step[j] == s:
            j += 1
        na = i - i0
        nb = j - j0
        na_out[g] = na
        nb_out[g] = nb
        if na == 0 and nb == 0:
            continue
        if na == 0 or nb == 0:
            # stuck side: point mass at 0
            total = 0.0
            if na == 0:
                for q in range(j0, j):
                    total += abs(b_val[q])
                w[g] = total / nb
            else:
                for p in range(i0, i):
                    total += abs(a_val[p])
                w[g] = total / na
            continue
        wa = 1.0 / na
        wb = 1.0 / nb
        p = i0
        q = j0
        diff = 0.0  # F_a - F_b just after the previous value
        prev = min(a_val[p], b_val[q])
        total = 0.0
        while p < i or q < j:
            if q >= j or (p < i and a_val[p] <= b_val[q]):
                x = a_val[p]
                total += abs(diff) * (x - prev)
                diff += wa
                p += 1
            else:
                x = b_val[q]
                total += abs(diff) * (x - prev)
                diff -= wb
                q += 1
            prev = x
        w[g] = total
    return w, na_out, nb_out


@numba.njit(cache=True, nogil=True)
def _sorted_by_step(step, value, span):  # pragma: no cover - compiled
    """``(step, value)`` sorted by step, then value.

    The simulated flights come in time order, so their steps are already ascending
    (the protocol's steps in recording order): then only each step's run of values is
    sorted, which is several times faster than one sort of ``n`` keys. Otherwise the key
    ``step * span + value`` of :func:`bouncelab.gap.distances._sorted_values` is sorted.
    """
    n = step.shape[0]
    ascending = True
    for i in range(1, n):
        if step[i] < step[i - 1]:
            ascending = False
            break
    if not ascending:
        key = step.astype(np.float64) * span + value
        order = np.argsort(key, kind="mergesort")
        return step[order], value[order]
    out = value.copy()
    i0 = 0
    for i in range(1, n + 1):
        if i == n or step[i] != step[i0]:
            out[i0:i] = np.sort(value[i0:i])
            i0 = i
    return step.copy(), out


@numba.njit(cache=True, nogil=True, parallel=True)
def ensemble_gaps(
    member, step, t, settled, n_members, min_t, grid,
    data_t_step, data_t_val, data_p_step, data_p_val, directions, alpha, scale, span,
):  # pragma: no cover - compiled  # fmt: skip
    """Per-step gap of each member of a simulated ensemble against the data, in one pass.

    The same numbers as :func:`bouncelab.gap.distances.prepare_flights` of each member's
    flights then :func:`bouncelab.gap.distances.step_distances` member by member, combined as
    ``alpha * w1_T + (1 - alpha) * scale * mean_k w_k`` (``w_k`` the Wasserstein-1
    distance of the return-map pairs projected on direction ``k``), without the Python
    around them: that was a third of every model evaluation.

    Parameters
    ----------
    member, step : int64[n]; t : float64[n] rad; settled : bool[n]: the simulated
        flights, in time order within each member.
    n_members : members 0..n_members-1; min_t : rad, shorter flights are dropped first.
    grid : int64[G], ascending steps to report.
    data_t_step, data_t_val : the data's settled flights sorted by ``(step, value)``.
    data_p_step, data_p_val : int64[K, m], float64[K, m]: the data's return-map pairs
        projected on each direction, each row sorted by ``(step, value)``.
    directions : float64[K, 2]; alpha, scale : weights of the two distances.
    span : the sort key's step spacing (:data:`bouncelab.gap.distances.KEY_SPAN`).

    Returns
    -------
    float64[n_members, G], rad.
    """
    n_dir = directions.shape[0]
    out = np.zeros((n_members, grid.shape[0]))
    # each member's flights: a block of the arrays when the members come in order (as
    # protocol_flight_times gives them), found once, instead of a mask over all flights
    # per member (most of this kernel's time on chatter-rich runs)
    in_blocks = True
    for i in range(1, member.shape[0]):
        if member[i] < member[i - 1]:
            in_blocks = False
            break
    bounds = (
        np.searchsorted(member, np.arange(n_members + 1)) if in_blocks else np.zeros(0, np.int64)
    )
    # members in parallel (each writes its own row: the same numbers on any thread count);
    # a fit's evaluation pool sets its workers to one thread each
    for m in numba.prange(n_members):
        if in_blocks:
            lo, hi = bounds[m], bounds[m + 1]
            long_enough = t[lo:hi] >= min_t
            s_m = step[lo:hi][long_enough]
            t_m = t[lo:hi][long_enough]
            ok = settled[lo:hi][long_enough]
        else:
            mine = (member == m) & (t >= min_t)
            s_m = step[mine]
            t_m = t[mine]
            ok = settled[mine]
        fs, fv = _sorted_by_step(s_m[ok], t_m[ok], span)
        w_t, _, _ = w1_by_step(grid, data_t_step, data_t_val, fs, fv)
        n = s_m.shape[0]
        pair = np.zeros(max(n - 1, 0), dtype=np.bool_)
        for i in range(n - 1):
            pair[i] = (s_m[i + 1] == s_m[i]) and ok[i] and ok[i + 1]
        idx = np.flatnonzero(pair)
        p_step = s_m[idx]
        x = t_m[idx]
        y = t_m[idx + 1]
        sliced = np.zeros(grid.shape[0])
        for k in range(n_dir):
            ps, pv = _sorted_by_step(p_step, x * directions[k, 0] + y * directions[k, 1], span)
            w_k, _, _ = w1_by_step(grid, data_p_step[k], data_p_val[k], ps, pv)
            sliced += w_k
        sliced *= scale / max(n_dir, 1)
        out[m] = alpha * w_t + (1.0 - alpha) * sliced
    return out
