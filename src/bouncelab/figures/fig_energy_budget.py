"""Energy budget per drive cycle across Gamma, per model variant (not in the seed)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from bouncelab.figures.style import legend_below, new_figure, variant_styles


def make(budget: pd.DataFrame, run_id: str):
    """Friction and impact losses per drive cycle against Gamma, one line per variant.

    ``budget``: the pipeline's energy table (``variant``, ``gamma``, ``friction_j``,
    ``impact_j``, ``plate_j``). Data: per variant the mean loss shares.
    """
    fig, (ax_f, ax_i) = new_figure(1, 2, width_in=8.0, height_in=3.8, sharey=False)
    out = {"run": run_id, "variants": {}}
    styles = variant_styles(budget["variant"].unique())
    for variant, grp in budget.groupby("variant", sort=False):
        grp = grp.sort_values("gamma")
        ax_f.plot(grp["gamma"], grp["friction_j"] * 1e3, lw=1, label=variant, **styles[variant])
        ax_i.plot(grp["gamma"], grp["impact_j"] * 1e3, lw=1, label=variant, **styles[variant])
        lost = grp["friction_j"].sum() + grp["impact_j"].sum()
        out["variants"][variant] = {
            "friction_share": float(grp["friction_j"].sum() / lost) if lost > 0 else np.nan,
            "max_plate_work_mj_per_cycle": float(grp["plate_j"].max() * 1e3) if len(grp) else None,
        }
    ax_f.set_title("lost to friction on the guide")
    ax_i.set_title("lost in impacts")
    for ax in (ax_f, ax_i):
        ax.set_xlabel(r"$\Gamma$")
        ax.set_ylabel("mJ per drive cycle")
    fig.suptitle(f"{run_id}: energy budget of the model variants")
    legend_below(fig, ax_i)  # one for both panels; inside, it hid the lines it names
    shares = [
        f"{v}: {d['friction_share']:.0%} friction"
        for v, d in out["variants"].items()
        if d["friction_share"] == d["friction_share"]
    ]
    out["summary"] = "share of the losses due to friction, " + "; ".join(shares) + "."
    return fig, out
