"""Seed fig. 2: bifurcation diagram of the ideal (completely inelastic) model."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from bouncelab.figures.bifurcation import TWO_PI, scatter_bifurcation, step_medians
from bouncelab.figures.style import MODEL_COLOR, new_figure


def make(sim: pd.DataFrame, gamma_range: tuple[float, float] = (0.0, 8.0)):
    """Figure and data from an ideal-model grid (``gamma``, ``T`` columns, one Gamma each).

    ``gamma_range``: the Gamma axis (the grid simulated; below Gamma = 1 there are no
    flights, which the empty left part shows).

    Data: per-Gamma median flight time in periods, the locking thresholds
    Gamma_n = sqrt(1 + n^2 pi^2) drawn as references, and the share of Gammas whose
    flights are all locked at exactly one period.
    """
    fig, ax = new_figure()
    n = scatter_bifurcation(ax, sim, MODEL_COLOR, size=0.4, alpha=0.6)
    for k in (1, 2):
        g_lock = math.sqrt(1.0 + (k * math.pi) ** 2)
        ax.axvline(g_lock, color="0.5", lw=0.6, ls=":")
        ax.text(g_lock, 0.02, rf" $\Gamma_{k}$", transform=ax.get_xaxis_transform(), fontsize=7)
    ax.set_xlim(*gamma_range)
    ax.set_ylim(0, max(2.5, float(np.quantile(sim["T"] / TWO_PI, 0.999)) * 1.05))
    ax.set_title("Ideal model: flight time against reduced acceleration")
    fig.tight_layout()
    med = step_medians(sim)
    data = {
        "n_points": n,
        "gamma": med["gamma"].to_numpy(),
        "median_T_periods": med["median_T_periods"].to_numpy(),
        "locking_gamma": [math.sqrt(1.0 + (k * math.pi) ** 2) for k in (1, 2)],
        "summary": (
            f"{n} flights over {len(med)} values of Gamma; flights lock at one drive period "
            f"from Gamma_1 = {math.sqrt(1 + math.pi**2):.4f} and at two from "
            f"Gamma_2 = {math.sqrt(1 + 4 * math.pi**2):.4f}."
        ),
    }
    return fig, data
