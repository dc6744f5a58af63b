"""Seed fig. 9: the model with and without Coulomb friction, over the data."""

from __future__ import annotations

from bouncelab.figures.bifurcation import (
    gamma_limits,
    max_periods,
    scatter_bifurcation,
    step_medians,
)
from bouncelab.figures.style import DATA_COLOR, new_figure


def make(flights, ideal, friction, run_id: str, mu: float | None = None):
    """Three layers on one axes: data (grey), ideal (blue), friction (red).

    Data: per-step median T of each, and the median absolute difference (periods)
    between data and each model over the steps both have.
    """
    fig, ax = new_figure(width_in=7.0, height_in=3.8)
    scatter_bifurcation(ax, flights, DATA_COLOR, label="data", alpha=0.35)
    scatter_bifurcation(ax, ideal, "#1f77b4", label="ideal", alpha=0.5)
    lab = "friction" + (f" (mu = {mu:.3f})" if mu is not None else "")
    scatter_bifurcation(ax, friction, "#d62728", label=lab, alpha=0.5)
    lo, hi = gamma_limits(flights, ideal, friction)
    ax.set_xlim(lo, hi)
    ax.set_ylim(0, max_periods(flights, ideal, friction))
    ax.legend(markerscale=12, loc="upper left")
    ax.set_title(f"{run_id}: model with and without Coulomb friction")
    fig.tight_layout()
    md = step_medians(flights).set_index("gamma")["median_T_periods"]
    out = {"run": run_id, "mu": mu}
    for name, tab in (("ideal", ideal), ("friction", friction)):
        mm = step_medians(tab).set_index("gamma")["median_T_periods"]
        both = md.index.intersection(mm.index)
        diff = (md[both] - mm[both]).abs()
        out[f"{name}_median_abs_diff_periods"] = float(diff.median()) if len(both) else None
    out["summary"] = (
        "median |data - model| of the per-step median flight time: "
        f"ideal {out['ideal_median_abs_diff_periods']:.3f} periods, "
        f"friction {out['friction_median_abs_diff_periods']:.3f} periods."
        if out["ideal_median_abs_diff_periods"] is not None
        and out["friction_median_abs_diff_periods"] is not None
        else "no Gamma step with flights in both data and models."
    )
    return fig, out
