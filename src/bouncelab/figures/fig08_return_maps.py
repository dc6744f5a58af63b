"""Seed fig. 8: return maps T(n+1) against T(n) at three Gamma."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from bouncelab.figures.bifurcation import TWO_PI, settled
from bouncelab.figures.style import DATA_COLOR, MODEL_COLOR, new_figure


def return_pairs(flights: pd.DataFrame, gamma: float) -> np.ndarray:
    """Pairs (T_n, T_n+1) in periods of consecutive settled flights at the step nearest ``gamma``.

    Consecutive means adjacent within the same step (and the same ensemble member, if
    there is a ``start`` column). Returns an array of shape (n, 2); empty if none.
    """
    df = settled(flights)
    if df.empty:
        return np.empty((0, 2))
    steps = np.unique(df["gamma"].to_numpy())
    g = steps[np.argmin(np.abs(steps - gamma))]
    sel = df[df["gamma"] == g]
    keys = ["step"] if "step" in sel else []
    if "start" in sel:
        keys.append("start")
    groups = sel.groupby(keys, sort=True) if keys else [(None, sel)]
    pairs = []
    for _, grp in groups:
        t = grp["T"].to_numpy() / TWO_PI
        if t.size > 1:
            pairs.append(np.column_stack([t[:-1], t[1:]]))
    return np.concatenate(pairs) if pairs else np.empty((0, 2))


def nearest_gamma(flights: pd.DataFrame, gamma: float) -> float:
    """The Gamma of the step nearest to ``gamma`` (NaN if there are no flights)."""
    g = settled(flights)["gamma"].to_numpy()
    return float(g[np.argmin(np.abs(g - gamma))]) if g.size else math.nan


def make(flights: pd.DataFrame, gammas, run_id: str, model: pd.DataFrame | None = None):
    """One panel per requested Gamma (the nearest measured step), data and optional model.

    Data: per panel the Gamma used, the number of pairs, and the number of distinct
    flight-time clusters (a period-n orbit shows n points).
    """
    gammas = list(gammas)
    # tall enough for square panels with their labels: at 3.1 in tight_layout left the
    # T_n labels below the figure's bottom edge
    fig, axes = new_figure(1, len(gammas), width_in=3.0 * len(gammas), height_in=3.6)
    axes = np.atleast_1d(axes)
    panels = []
    for ax, gamma in zip(axes, gammas, strict=True):
        g = nearest_gamma(flights, gamma)
        pd_ = return_pairs(flights, gamma)
        if model is not None:
            pm = return_pairs(model, g if math.isfinite(g) else gamma)
            ax.scatter(pm[:, 0], pm[:, 1], s=4, c=MODEL_COLOR, alpha=0.4, lw=0, label="model")
        ax.scatter(pd_[:, 0], pd_[:, 1], s=4, c=DATA_COLOR, alpha=0.7, lw=0, label="data")
        hi = max(1.0, float(np.max(pd_)) * 1.1) if pd_.size else 1.0
        ax.plot([0, hi], [0, hi], color="0.6", lw=0.6, ls=":")
        ax.set_xlim(0, hi)
        ax.set_ylim(0, hi)
        ax.set_aspect("equal")
        ax.set_title(rf"$\Gamma$ = {g:.3g}" if math.isfinite(g) else "no flights")
        ax.set_xlabel(r"$T_n$ (periods)")
        panels.append({"gamma_requested": gamma, "gamma": g, "n_pairs": int(len(pd_))})
    axes[0].set_ylabel(r"$T_{n+1}$ (periods)")
    if model is not None:
        axes[0].legend(markerscale=3, loc="upper left")
    fig.suptitle(f"{run_id}: return maps")
    fig.tight_layout()
    data = {
        "run": run_id,
        "panels": panels,
        "summary": "; ".join(
            f"Gamma {p['gamma']:.3g}: {p['n_pairs']} pairs"
            for p in panels
            if math.isfinite(p["gamma"])
        )
        + ".",
    }
    return fig, data
