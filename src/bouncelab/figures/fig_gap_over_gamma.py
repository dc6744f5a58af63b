"""The gap between data and each model variant over Gamma (not in the seed)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from bouncelab.figures.style import legend_below, new_figure, variant_styles

#: Colour of a step where every variant is within the noise floor (none is closest).
WITHIN_FLOOR_COLOR = "0.85"


def closest_by_step(compare: pd.DataFrame) -> pd.DataFrame:
    """Per protocol step, the variant with the least relative gap.

    ``compare``: the pipeline's comparison table (``variant``, ``step``, ``gamma``,
    ``rel_gap``). Returns one row per step (``step``, ``gamma``, ``variant``,
    ``rel_gap``), in step order; ``variant`` is None where every variant lies within
    the noise floor (``rel_gap <= 1``), since none is then closer than the data's own
    scatter says. Ties go to the variant listed first. Steps without a finite gap are
    left out.
    """
    keyed = compare.assign(order=pd.factorize(compare["variant"])[0])
    keyed = keyed[np.isfinite(keyed["rel_gap"].to_numpy(dtype=float))]
    if keyed.empty:
        return pd.DataFrame(columns=["step", "gamma", "variant", "rel_gap"])
    best = keyed.sort_values(["step", "rel_gap", "order"], kind="stable").groupby("step").first()
    worst = keyed.groupby("step")["rel_gap"].max()
    out = best.reset_index()[["step", "gamma", "variant", "rel_gap"]]
    out["variant"] = out["variant"].astype(object).where(worst.to_numpy() > 1.0, None)
    return out


def make(compare: pd.DataFrame, run_id: str):
    """Relative gap (gap / noise floor) per step, one line per variant, log scale; below
    it a strip with the closest variant at each step.

    ``compare``: the pipeline's comparison table (``variant``, ``step``, ``gamma``,
    ``gap``, ``floor_used``, ``rel_gap``). A model that matches the data sits near 1.
    Data: per variant the median relative gap, the Gamma of its largest gap and the
    steps where it is the closest (:func:`closest_by_step`).
    """
    fig, (ax, ax_best) = new_figure(
        2, 1, width_in=7.0, height_in=4.8, sharex=True, gridspec_kw={"height_ratios": [6, 1]}
    )
    out = {"run": run_id, "variants": {}}
    styles = variant_styles(compare["variant"].unique())
    best = closest_by_step(compare)
    for variant, grp in compare.groupby("variant", sort=False):
        grp = grp.sort_values("gamma")
        rel = grp["rel_gap"].to_numpy()
        ax.plot(
            grp["gamma"], np.maximum(rel, 1e-2), lw=1, marker=".", ms=2, label=variant,
            **styles[variant],
        )  # fmt: skip
        worst = int(np.nanargmax(rel)) if np.isfinite(rel).any() else None
        out["variants"][variant] = {
            "median_rel_gap": float(np.nanmedian(rel)) if rel.size else None,
            "mean_gap_rad": float(np.nanmean(grp["gap"])) if len(grp) else None,
            "worst_gamma": float(grp["gamma"].iloc[worst]) if worst is not None else None,
            "closest_steps": int((best["variant"] == variant).sum()),
        }
    ax.axhline(1.0, color="0.3", lw=0.8, ls="--")
    ax.text(0.01, 1.05, "noise floor", transform=ax.get_yaxis_transform(), fontsize=7)
    ax.set_yscale("log")
    ax.set_ylabel("gap / noise floor")
    ax.set_title(f"{run_id}: gap between data and model variants")
    _draw_closest(ax_best, best, styles)
    ax_best.set_xlabel(r"$\Gamma$")
    legend_below(fig, ax)  # inside the axes it hid the large gaps near takeoff
    ranked = sorted(
        (d["median_rel_gap"], v)
        for v, d in out["variants"].items()
        if d["median_rel_gap"] is not None
    )
    counts = sorted(
        ((d["closest_steps"], v) for v, d in out["variants"].items() if d["closest_steps"]),
        reverse=True,
    )
    out["within_floor_steps"] = int(best["variant"].isna().sum())
    out["summary"] = (
        "median gap / noise floor: "
        + "; ".join(f"{v} {m:.1f}" for m, v in ranked)
        + (f". Closest variant: {ranked[0][1]}." if ranked else ".")
        + (
            " Closest per step: " + "; ".join(f"{v} at {n}" for n, v in counts) + " steps"
            if counts
            else ""
        )
        + (
            f"; every variant within the floor at {out['within_floor_steps']}."
            if out["within_floor_steps"]
            else "."
        )
    )
    return fig, out


def _draw_closest(ax, best: pd.DataFrame, styles: dict) -> None:
    """One bar per step, coloured by its closest variant (:func:`closest_by_step`), grey
    where every variant is within the floor."""
    gamma = best["gamma"].to_numpy(dtype=float)
    if gamma.size:
        # each bar spans half way to its neighbours in Gamma, at most half the usual step:
        # a range without steps (a data gap) stays blank
        order = np.argsort(gamma, kind="stable")
        g = gamma[order]
        half = np.median(np.diff(g)) / 2.0 if g.size > 1 else 0.05
        mid = 0.5 * (g[1:] + g[:-1])
        lo = np.maximum(np.concatenate([[g[0] - half], mid]), g - half)
        hi = np.minimum(np.concatenate([mid, [g[-1] + half]]), g + half)
        for k, i in enumerate(order):
            name = best["variant"].iloc[i]
            color = styles[name]["color"] if name is not None else WITHIN_FLOOR_COLOR
            ax.axvspan(lo[k], hi[k], color=color, lw=0)
    ax.set_yticks([])
    ax.set_ylabel("closest", rotation=0, ha="right", va="center", fontsize=8)
    ax.grid(False)
