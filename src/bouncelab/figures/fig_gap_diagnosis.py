"""The gap of a sweep run over Gamma before and after each accepted effect.

Built from the diagnosis JSON alone (``bouncelab diagnose``; its ``profile`` key), so the
figure can be redrawn without refitting.
"""

from __future__ import annotations

import numpy as np

from bouncelab.figures.style import DATA_COLOR, MODEL_COLOR, new_figure


def _explained_spans(regions: list[dict]) -> list[tuple[float, float, str]]:
    """Gamma spans of adjacent regions explained by the same effect, merged (one label)."""
    spans: list[tuple[float, float, str]] = []
    for reg in regions:
        eff = reg.get("explained_by")
        if not eff:
            continue
        if spans and spans[-1][2] == eff:
            spans[-1] = (spans[-1][0], reg["gamma_max"], eff)
        else:
            spans.append((reg["gamma_min"], reg["gamma_max"], eff))
    return spans


def make(diagnosis: dict):
    """Per-step gap (rad, log scale) over Gamma: baseline, after each accepted effect, and
    the data's noise floor; held-out steps as open markers; regions shaded by effect.

    Parameters
    ----------
    diagnosis : dict of :func:`bouncelab.gap.diagnose.diagnose_run` (CONTRACTS.md
        section 6 with the ``profile`` key).

    Returns
    -------
    (Figure, dict): the figure and the numbers it shows.
    """
    prof = diagnosis["profile"]
    gamma = np.asarray(prof["gamma"], dtype=float)
    held = np.asarray(prof["heldout"], dtype=bool)
    floor = np.asarray(prof["noise_floor"], dtype=float)
    tiny = 1e-4  # rad: a gap of 0 (both sides stuck) is drawn at the bottom of the log axis
    curves = [("baseline: " + diagnosis["baseline"]["model"], prof["gap_baseline"])]
    names = []
    for after in prof["gap_after"]:
        names.append(after["effect"])
        curves.append(("+ " + " + ".join(names), after["gap"]))
    fig, ax = new_figure(1, 1, width_in=7.5, height_in=3.6)
    for lo, hi, effect in _explained_spans(diagnosis["regions"]):
        ax.axvspan(lo, hi, color="#2ca02c", alpha=0.08, lw=0)
        ax.text(
            0.5 * (lo + hi), 1.0, effect, transform=ax.get_xaxis_transform(),
            ha="center", va="bottom", fontsize=7,
        )  # fmt: skip
    ax.plot(gamma, np.maximum(floor, tiny), color="#888888", ls="--", lw=1, label="noise floor")
    colors = [DATA_COLOR, MODEL_COLOR, "#1f77b4", "#9467bd", "#ff7f0e", "#8c564b"]
    for (label, gaps), color in zip(curves, colors, strict=False):
        g = np.maximum(np.asarray(gaps, dtype=float), tiny)
        ax.plot(gamma, g, color=color, lw=1, label=label)
        ax.plot(gamma[~held], g[~held], "o", ms=2.5, color=color)
        ax.plot(gamma[held], g[held], "o", ms=3.5, mfc="none", color=color)
    ax.set_yscale("log")
    ax.set_xlabel("Gamma (stated)")
    ax.set_ylabel("gap per step (rad)")
    sel = ", ".join(diagnosis["selected"]) or "nothing"
    verdict = "unexplained" if diagnosis["unexplained"] else "explained"
    # the padding leaves a line above the axes for the regions' names, drawn there
    ax.set_title(f"{diagnosis['run']}: selected {sel} ({verdict}); open markers held out", pad=12)
    ax.legend(loc="lower right", ncol=2)
    fig.tight_layout()
    data = {
        "run": diagnosis["run"],
        "gamma": gamma,
        "heldout": held,
        "noise_floor": floor,
        "curves": {label: np.asarray(g, dtype=float) for label, g in curves},
        "selected": diagnosis["selected"],
        "baseline_gap": diagnosis["baseline"]["gap"],
        "final_gap": diagnosis["final_gap"],
        "unexplained": diagnosis["unexplained"],
        "summary": (
            f"held-out gap {diagnosis['baseline']['gap']:.3g} rad with "
            f"{diagnosis['baseline']['model']}, {diagnosis['final_gap']:.3g} rad after "
            f"{sel} (noise floor {diagnosis['noise_floor']:.3g} rad): {verdict}"
        ),
    }
    return fig, data
