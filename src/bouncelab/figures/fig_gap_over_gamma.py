"""The gap between data and each model variant over Gamma (not in the seed)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from bouncelab.figures.style import new_figure


def make(compare: pd.DataFrame, run_id: str):
    """Relative gap (gap / noise floor) per step, one line per variant, log scale.

    ``compare``: the pipeline's comparison table (``variant``, ``gamma``, ``gap``,
    ``floor_used``, ``rel_gap``). A model that matches the data sits near 1.
    Data: per variant the median relative gap and the Gamma of its largest gap.
    """
    fig, ax = new_figure(width_in=7.0, height_in=3.6)
    out = {"run": run_id, "variants": {}}
    for variant, grp in compare.groupby("variant", sort=False):
        grp = grp.sort_values("gamma")
        rel = grp["rel_gap"].to_numpy()
        ax.plot(grp["gamma"], np.maximum(rel, 1e-2), lw=1, marker=".", ms=2, label=variant)
        worst = int(np.nanargmax(rel)) if np.isfinite(rel).any() else None
        out["variants"][variant] = {
            "median_rel_gap": float(np.nanmedian(rel)) if rel.size else None,
            "mean_gap_rad": float(np.nanmean(grp["gap"])) if len(grp) else None,
            "worst_gamma": float(grp["gamma"].iloc[worst]) if worst is not None else None,
        }
    ax.axhline(1.0, color="0.3", lw=0.8, ls="--")
    ax.text(0.01, 1.05, "noise floor", transform=ax.get_yaxis_transform(), fontsize=7)
    ax.set_yscale("log")
    ax.set_xlabel(r"$\Gamma$")
    ax.set_ylabel("gap / noise floor")
    ax.set_title(f"{run_id}: gap between data and model variants")
    ax.legend(fontsize=6, ncol=2, loc="upper left")
    fig.tight_layout()
    ranked = sorted(
        (d["median_rel_gap"], v)
        for v, d in out["variants"].items()
        if d["median_rel_gap"] is not None
    )
    out["summary"] = (
        "median gap / noise floor: "
        + "; ".join(f"{v} {m:.1f}" for m, v in ranked)
        + (f". Closest variant: {ranked[0][1]}." if ranked else ".")
    )
    return fig, out
