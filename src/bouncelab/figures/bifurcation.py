"""Shared drawing of bifurcation diagrams: flight time in drive periods against Gamma."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

TWO_PI = 2.0 * math.pi


def settled(flights: pd.DataFrame) -> pd.DataFrame:
    """Only the flights that count (``settled`` true, where the column exists)."""
    if "settled" in flights:
        return flights[flights["settled"].astype(bool)]
    return flights


def scatter_bifurcation(ax, flights: pd.DataFrame, color, label=None, size=0.6, alpha=0.5):
    """Scatter T / 2 pi (drive periods) against Gamma on ``ax``; returns the point count."""
    df = settled(flights)
    ax.scatter(
        df["gamma"].to_numpy(),
        df["T"].to_numpy() / TWO_PI,
        s=size,
        c=color,
        alpha=alpha,
        linewidths=0,
        rasterized=True,
        label=label,
    )
    ax.set_xlabel(r"$\Gamma$")
    ax.set_ylabel("flight time T (drive periods)")
    return len(df)


def step_medians(flights: pd.DataFrame) -> pd.DataFrame:
    """Per-Gamma median flight time (periods) and count of settled flights."""
    df = settled(flights)
    if df.empty:
        return pd.DataFrame({"gamma": [], "median_T_periods": [], "n": []})
    g = df.groupby("gamma", sort=True)["T"]
    return pd.DataFrame(
        {
            "gamma": g.median().index.to_numpy(),
            "median_T_periods": g.median().to_numpy() / TWO_PI,
            "n": g.size().to_numpy(),
        }
    )


def gamma_limits(*tables: pd.DataFrame) -> tuple[float, float]:
    """Gamma range covering every table, starting at 0 as the seed's diagrams do."""
    hi = max((float(t["gamma"].max()) for t in tables if len(t)), default=1.0)
    return 0.0, max(1.0, math.ceil(hi * 2.0) / 2.0)


def max_periods(*tables: pd.DataFrame) -> float:
    """Upper limit of the T axis in periods (the 99.9th percentile, rounded up)."""
    vals = [settled(t)["T"].to_numpy() / TWO_PI for t in tables if len(t)]
    vals = [v for v in vals if v.size]
    if not vals:
        return 1.0
    return float(max(1.0, math.ceil(np.quantile(np.concatenate(vals), 0.999) * 4) / 4))
