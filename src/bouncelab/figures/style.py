"""House style and deterministic saving of figures.

PNG files carry no timestamp or software version, SVG ids are salted with a fixed
string, and the figure data is written as sorted, rounded JSON, so that two clean runs
give byte-identical files.
"""

from __future__ import annotations

import json
import math
from contextlib import contextmanager
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # no display needed, and the same rasteriser everywhere

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

RC = {
    "figure.dpi": 100,
    "savefig.dpi": 110,
    "font.family": "DejaVu Sans",  # shipped with matplotlib: the same glyphs on every machine
    "font.size": 9,
    "axes.titlesize": 10,
    "axes.labelsize": 9,
    "legend.fontsize": 8,
    "axes.grid": True,
    "grid.alpha": 0.3,
    "svg.hashsalt": "bouncelab",
    "path.simplify": True,
    "axes.prop_cycle": matplotlib.cycler(
        color=["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#17becf"]
    ),
}

#: colour of measured data and of models in every figure
DATA_COLOR = "#222222"
MODEL_COLOR = "#d62728"

#: Line colours of the model variants after ``ideal`` (black), in the config's order.
#: Nine, so that the default eight variants each get their own: the house cycle's seven
#: gave the eighth (``friction+restitution+feedback``) the first's blue.
VARIANT_COLORS = (
    "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b",
    "#17becf", "#1f77b4", "#e377c2", "#bcbd22",
)  # fmt: skip


def variant_styles(names) -> dict[str, dict]:
    """Line style of each model variant, ``{name: {"color": ..., "ls": ...}}``.

    ``names``: the variants in the order a figure draws them (the config's). ``ideal`` is
    black; the others take :data:`VARIANT_COLORS` in turn, solid for one effect and dashed
    for a combination (a ``+`` in the name), so that every figure of a run draws a variant
    with the same line. Past nine, the colours repeat dotted.
    """
    styles = {}
    others = [n for n in dict.fromkeys(names) if n != "ideal"]
    for name in dict.fromkeys(names):
        if name == "ideal":
            styles[name] = {"color": DATA_COLOR, "ls": "-"}
            continue
        i = others.index(name)
        lap = i // len(VARIANT_COLORS)
        ls = ":" if lap else ("--" if "+" in name else "-")
        styles[name] = {"color": VARIANT_COLORS[i % len(VARIANT_COLORS)], "ls": ls}
    return styles


@contextmanager
def house_style():
    """Context in which figures are built: fixed rcParams, independent of the user's."""
    with plt.rc_context(RC):
        yield


def new_figure(nrows=1, ncols=1, width_in=7.0, height_in=3.6, **kwargs):
    """A Figure and its axes in the house style (call inside :func:`house_style`)."""
    fig, axes = plt.subplots(nrows, ncols, figsize=(width_in, height_in), **kwargs)
    return fig, axes


def legend_below(fig, ax, ncol: int = 4, fontsize: float = 7.0) -> None:
    """One legend of ``ax``'s lines under the whole figure, then ``tight_layout`` above it.

    For figures of many lines (the model variants), where a legend inside the axes hides
    the lines it names. Reserves one text line (``fontsize`` points, with spacing) per
    legend row.
    """
    handles, labels = ax.get_legend_handles_labels()
    bottom = 0.0
    if handles:
        rows = math.ceil(len(handles) / ncol)
        fig.legend(handles, labels, loc="lower center", ncol=ncol, fontsize=fontsize,
                   frameon=False)  # fmt: skip
        height_pt = fig.get_figheight() * 72.0
        bottom = min(0.5, (rows * 1.6 * fontsize + 6.0) / height_pt)
    fig.tight_layout(rect=(0, bottom, 1, 1))


def _clean(value, digits=9):
    """JSON-safe, rounded copy of ``value`` (NaN and infinities become None)."""
    if isinstance(value, dict):
        return {str(k): _clean(v, digits) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_clean(v, digits) for v in value]
    if isinstance(value, np.ndarray):
        return [_clean(v, digits) for v in value.tolist()]
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        v = float(value)
        if not math.isfinite(v):
            return None
        return float(f"{v:.{digits}g}")
    if isinstance(value, np.bool_):
        return bool(value)
    return value


def save_figure(fig, png_path, data=None, data_path=None, dpi=110) -> None:
    """Write ``fig`` as a PNG without metadata, and ``data`` as sorted JSON.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
    png_path : path of the PNG
    data : dict of the numbers the figure shows (optional)
    data_path : path of the JSON (defaults to the PNG path with ``.json``)
    dpi : resolution in dots per inch
    """
    png_path = Path(png_path)
    png_path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(png_path, dpi=dpi, metadata={"Software": None})
    plt.close(fig)
    if data is not None:
        data_path = Path(data_path) if data_path else png_path.with_suffix(".json")
        data_path.write_text(json.dumps(_clean(data), indent=1, sort_keys=True) + "\n")
