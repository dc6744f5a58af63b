"""Blind validation of the gap diagnosis: confusion matrix and parameter recovery errors.

Built from ``scores.json`` of :mod:`bouncelab.gap.blind` alone.
"""

from __future__ import annotations

import numpy as np

from bouncelab.figures.style import new_figure


def make(scores: dict):
    """Left: true effect (rows) against the top selected effect (columns) for the null and
    single-effect cases. Right: relative recovery error of each parameter (dots), with the
    15 % goal.

    Parameters
    ----------
    scores : the content of ``scores.json`` (``cases``, ``summary``).

    Returns
    -------
    (Figure, dict)
    """
    summ = scores["summary"]
    labels = summ["labels"]
    cm = np.asarray(summ["confusion"], dtype=int)
    fig, (ax_c, ax_e) = new_figure(1, 2, width_in=8.5, height_in=3.8)
    ax_c.imshow(cm, cmap="Blues", vmin=0, vmax=max(1, int(cm.max())))
    ax_c.grid(False)
    ax_c.set_xticks(range(len(labels)), labels, rotation=45, ha="right")
    ax_c.set_yticks(range(len(labels)), labels)
    ax_c.set_xlabel("top selected effect")
    ax_c.set_ylabel("true effect")
    for i in range(cm.shape[0]):
        for j in range(cm.shape[1]):
            if cm[i, j]:
                ax_c.text(j, i, str(cm[i, j]), ha="center", va="center", fontsize=8)
    right = summ["top_effect_right"]
    ax_c.set_title(
        "top effect right: " + (f"{right:.0%}" if right is not None else "n/a")
        + f"; null false alarms {summ['null_false_alarms']}/{summ['n_null']}"
    )  # fmt: skip
    errs = summ["param_errors"]
    names = list(errs)
    for i, name in enumerate(names):
        v = np.asarray(errs[name], dtype=float)
        ax_e.plot(np.full(len(v), i), 100 * v, "o", ms=4, color="#1f77b4")
    ax_e.axhline(15, color="#d62728", ls="--", lw=1, label="goal 15 %")
    ax_e.set_xticks(range(len(names)), names, rotation=45, ha="right")
    ax_e.set_xlim(-0.5, max(len(names), 1) - 0.5)
    ax_e.set_ylabel("relative error (%)")
    ax_e.set_yscale("symlog", linthresh=1.0)
    ax_e.set_ylim(bottom=0.0)
    ax_e.set_title(
        f"recovery; out-of-library flagged {summ['outside_flagged']}/{summ['n_outside']}"
    )
    ax_e.legend(loc="upper left")
    fig.tight_layout()
    data = {
        "labels": labels,
        "confusion": cm,
        "param_errors": errs,
        "top_effect_right": right,
        "null_false_alarms": summ["null_false_alarms"],
        "n_null": summ["n_null"],
        "outside_flagged": summ["outside_flagged"],
        "n_outside": summ["n_outside"],
        "summary": (
            f"{summ['n_single']} single-effect cases, top effect right "
            + (f"{right:.0%}" if right is not None else "n/a")
            + f"; {summ['null_false_alarms']} false alarms in {summ['n_null']} null cases; "
            f"{summ['outside_flagged']} of {summ['n_outside']} out-of-library cases flagged"
        ),
    }
    return fig, data
