"""Synthetic flight tables with planted properties, for the tests of ``bouncelab.gap``.

No physics: each step gets flight times that cycle through given values (a period-n
orbit) or are drawn from a given distribution, plus Gaussian timing noise. Columns as
in CONTRACTS.md section 3 (``step``, ``gamma``, ``T``, ``phi_takeoff``, ``settled``,
``t_takeoff_s``), so the tables stand in for extracted or simulated flights.
"""

from __future__ import annotations

import numpy as np
import pandas as pd


def step_frame(step, gamma, T, *, phase=1.0, phase_noise=0.02, rng=None, t0=0.0, unsettled=0):
    """One step's flights, in time order; the first ``unsettled`` are not settled."""
    rng = np.random.default_rng(0) if rng is None else rng
    T = np.asarray(T, dtype=np.float64)
    n = len(T)
    return pd.DataFrame(
        {
            "step": np.full(n, step, dtype=np.int64),
            "gamma": np.full(n, gamma, dtype=np.float64),
            "T": T,
            "phi_takeoff": np.mod(phase + rng.normal(0.0, phase_noise, n), 2 * np.pi),
            "settled": np.arange(n) >= unsettled,
            # one drive period (1/30 s) per flight plus the flight: strictly increasing
            "t_takeoff_s": t0 + np.cumsum(np.full(n, 1 / 30) + T / (2 * np.pi * 30)),
        }
    )


def periodic_table(levels, gammas, *, n=80, noise=0.01, seed=0, phase=1.0, unsettled=0):
    """Steps ``0..len(gammas)-1``; step ``k`` cycles through ``levels[k]`` (rad).

    ``levels[k] = []`` leaves step ``k`` without flights (stuck on the plate).
    """
    rng = np.random.default_rng(seed)
    frames, t0 = [], 0.0
    for k, (lev, g) in enumerate(zip(levels, gammas, strict=True)):
        if len(lev) == 0:
            continue
        base = np.resize(np.asarray(lev, dtype=np.float64), n)
        T = np.abs(base + rng.normal(0.0, noise, n))
        frames.append(step_frame(k, g, T, phase=phase, rng=rng, t0=t0, unsettled=unsettled))
        t0 = frames[-1]["t_takeoff_s"].iloc[-1] + 1.0
    return pd.concat(frames, ignore_index=True)


def random_table(n_steps=40, n=100, *, loc=2.0, slope=0.05, scale=0.3, shift=0.0, seed=0):
    """Steps with i.i.d. flight times ``|N(loc + slope*k, scale)| + shift`` (rad)."""
    rng = np.random.default_rng(seed)
    frames, t0 = [], 0.0
    for k in range(n_steps):
        T = np.abs(rng.normal(loc + slope * k, scale, n)) + shift
        frames.append(step_frame(k, 1.0 + 0.1 * k, T, rng=rng, t0=t0))
        t0 = frames[-1]["t_takeoff_s"].iloc[-1] + 1.0
    return pd.concat(frames, ignore_index=True)
