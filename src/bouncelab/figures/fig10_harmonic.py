"""Seed fig. 10: the model with a harmonic added to the plate motion, over the data."""

from __future__ import annotations

from bouncelab.figures.bifurcation import (
    gamma_limits,
    max_periods,
    scatter_bifurcation,
    step_medians,
)
from bouncelab.figures.style import DATA_COLOR, MODEL_COLOR, new_figure


def make(flights, harmonic, run_id: str, params: dict | None = None):
    """Data (grey) and the harmonic model (red) under the run's protocol.

    Data: per-step median T of both, the harmonic parameters, and the median absolute
    difference of the per-step medians (periods).
    """
    fig, ax = new_figure(width_in=7.0, height_in=3.8)
    scatter_bifurcation(ax, flights, DATA_COLOR, label="data", alpha=0.35)
    p = params or {}
    lab = "harmonic"
    if {"k", "a", "psi"} <= set(p):
        lab += f" (k = {p['k']:g}, a = {p['a']:g}, psi = {p['psi']:g})"
    scatter_bifurcation(ax, harmonic, MODEL_COLOR, label=lab, alpha=0.5)
    lo, hi = gamma_limits(flights, harmonic)
    ax.set_xlim(lo, hi)
    ax.set_ylim(0, max_periods(flights, harmonic))
    ax.legend(markerscale=12, loc="upper left")
    ax.set_title(f"{run_id}: harmonic forcing model against the data")
    fig.tight_layout()
    md = step_medians(flights).set_index("gamma")["median_T_periods"]
    mm = step_medians(harmonic).set_index("gamma")["median_T_periods"]
    both = md.index.intersection(mm.index)
    diff = float((md[both] - mm[both]).abs().median()) if len(both) else None
    data = {
        "run": run_id,
        "params": p,
        "median_abs_diff_periods": diff,
        "summary": (
            f"median |data - model| of the per-step median flight time: {diff:.3f} periods."
            if diff is not None
            else "no Gamma step with flights in both data and model."
        ),
    }
    return fig, data
