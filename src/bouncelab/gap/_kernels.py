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
