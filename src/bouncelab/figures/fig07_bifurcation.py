"""Seed fig. 7 a-d: bifurcation diagrams of the data and of the model, side by side."""

from __future__ import annotations

import pandas as pd

from bouncelab.figures.bifurcation import (
    gamma_limits,
    max_periods,
    scatter_bifurcation,
    step_medians,
)
from bouncelab.figures.style import DATA_COLOR, MODEL_COLOR, new_figure


def make(flights: pd.DataFrame, model: pd.DataFrame, run_id: str, model_name: str = "ideal"):
    """Data (left) and model under the same protocol (right), same axes.

    Data: per-step median T (periods) of data and model, and the Gamma steps of each.
    """
    fig, (ax_d, ax_m) = new_figure(1, 2, width_in=8.0, height_in=3.4, sharey=True)
    n_d = scatter_bifurcation(ax_d, flights, DATA_COLOR)
    n_m = scatter_bifurcation(ax_m, model, MODEL_COLOR)
    lo, hi = gamma_limits(flights, model)
    top = max_periods(flights, model)
    for ax, title in ((ax_d, f"data: {run_id}"), (ax_m, f"model: {model_name}")):
        ax.set_xlim(lo, hi)
        ax.set_ylim(0, top)
        ax.set_title(title)
    ax_m.set_ylabel("")
    fig.tight_layout()
    md, mm = step_medians(flights), step_medians(model)
    data = {
        "run": run_id,
        "model": model_name,
        "n_data": n_d,
        "n_model": n_m,
        "data_gamma": md["gamma"].to_numpy(),
        "data_median_T_periods": md["median_T_periods"].to_numpy(),
        "model_gamma": mm["gamma"].to_numpy(),
        "model_median_T_periods": mm["median_T_periods"].to_numpy(),
        "summary": (
            f"{n_d} settled flights measured over {len(md)} Gamma steps; the {model_name} "
            f"model gives {n_m} under the same protocol."
        ),
    }
    return fig, data
