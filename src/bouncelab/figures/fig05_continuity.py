"""Seed fig. 5: a stretch of the continuity signal with the detected takeoffs and landings."""

from __future__ import annotations

import numpy as np
import pandas as pd

from bouncelab.figures.style import DATA_COLOR, new_figure

TAKEOFF_COLOR = "#2ca02c"
LANDING_COLOR = "#d62728"


def make(
    time_s: np.ndarray,
    volts: np.ndarray,
    flights: pd.DataFrame,
    run_id: str,
    gamma: float | None = None,
    levels: tuple[float, float] | None = None,
):
    """The signal (volts against milliseconds) with each detected flight shaded, and beside
    it one contact magnified: the samples and the sub-sample edges around it.

    ``time_s``, ``volts``: shape (n,), the stretch to show. ``flights``: rows with
    ``t_takeoff_s`` and ``t_landing_s`` (only those inside the stretch are drawn).
    ``levels``: optional (contact, open) levels in volts, drawn as dotted lines.
    Data: the stretch, the number of flights shown and their durations (ms), and the
    magnified contact (its landing and the next takeoff, s; None without one).

    Why the magnified contact: a contact lasts a fraction of a millisecond, so over the
    stretch a landing and the next takeoff fall on the same pixel column.
    """
    t0 = float(time_s[0])
    t1 = float(time_s[-1])
    inside = flights[(flights["t_takeoff_s"] >= t0) & (flights["t_landing_s"] <= t1)]
    inside = inside.sort_values("t_takeoff_s")
    fig, (ax, ax_zoom) = new_figure(
        1, 2, width_in=8.0, height_in=3.0, gridspec_kw={"width_ratios": [3, 1]}
    )
    ms = (time_s - t0) * 1e3
    ax.plot(ms, volts, color=DATA_COLOR, lw=0.7, drawstyle="steps-mid")
    for a, b in zip(inside["t_takeoff_s"], inside["t_landing_s"], strict=True):
        ax.axvspan((a - t0) * 1e3, (b - t0) * 1e3, color=TAKEOFF_COLOR, alpha=0.15, lw=0)
        ax.axvline((a - t0) * 1e3, color=TAKEOFF_COLOR, lw=0.6)
    for b in inside["t_landing_s"]:  # over the takeoffs: the next one is a pixel away
        ax.axvline((b - t0) * 1e3, color=LANDING_COLOR, lw=0.6, zorder=3)
    if levels is not None:
        for lev in levels:
            ax.axhline(lev, color="0.5", lw=0.6, ls=":")
    ax.set_xlim(0, (t1 - t0) * 1e3)
    ax.set_xlabel(f"time from t = {t0:.3f} s (ms)")
    ax.set_ylabel("continuity (V)")
    title = f"{run_id}: continuity signal"
    if gamma is not None:
        title += rf", $\Gamma$ = {gamma:g}"
    ax.set_title(title + " (green: takeoff, red: landing)")
    contact = _contact_nearest_middle(inside, 0.5 * (t0 + t1))
    _draw_contact(ax_zoom, time_s, volts, contact)
    fig.tight_layout()
    durations = (inside["t_landing_s"] - inside["t_takeoff_s"]).to_numpy() * 1e3
    data = {
        "run": run_id,
        "t_start_s": t0,
        "t_stop_s": t1,
        "gamma": gamma,
        "n_flights": int(len(inside)),
        "flight_ms": durations,
        "contact_shown_s": list(contact) if contact is not None else None,
        "summary": (
            f"{len(inside)} flights in {1e3 * (t1 - t0):.0f} ms"
            + (f" at Gamma = {gamma:g}" if gamma is not None else "")
            + (f", {durations.min():.2f} to {durations.max():.2f} ms long." if len(inside) else ".")
        ),
    }
    return fig, data


def _contact_nearest_middle(flights: pd.DataFrame, t_mid: float):
    """(landing, next takeoff) in s of the contact nearest ``t_mid`` between two of
    ``flights`` (sorted by takeoff), or None with fewer than two flights."""
    if len(flights) < 2:
        return None
    landing = flights["t_landing_s"].to_numpy()[:-1]
    takeoff = flights["t_takeoff_s"].to_numpy()[1:]
    i = int(np.argmin(np.abs(0.5 * (landing + takeoff) - t_mid)))
    return float(landing[i]), float(takeoff[i])


def _draw_contact(ax, time_s: np.ndarray, volts: np.ndarray, contact) -> None:
    """The samples around one contact, time in ms from its landing, with the detected
    sub-sample landing and takeoff; a note instead when there is no contact to show."""
    ax.set_title("one contact, magnified", fontsize=9)
    if contact is None:
        ax.text(0.5, 0.5, "no contact between\ntwo flights here", ha="center", va="center",
                transform=ax.transAxes, fontsize=8)  # fmt: skip
        ax.set_xticks([])
        ax.set_yticks([])
        return
    landing, takeoff = contact
    dt = float(np.median(np.diff(time_s))) if time_s.size > 1 else 0.0
    pad = max(6.0 * dt, takeoff - landing)  # a few samples, or the contact's own length
    near = (time_s >= landing - pad) & (time_s <= takeoff + pad)
    ms = (time_s[near] - landing) * 1e3
    ax.plot(ms, volts[near], color=DATA_COLOR, lw=0.6, marker=".", ms=3)
    ax.axvline(0.0, color=LANDING_COLOR, lw=0.8)
    ax.axvline((takeoff - landing) * 1e3, color=TAKEOFF_COLOR, lw=0.8)
    ax.set_xlabel("ms from the landing")


def choose_window(flights: pd.DataFrame, duration_s: float = 0.25, gamma_target: float = 2.5):
    """A stretch worth showing: in the settled part of the step nearest ``gamma_target``.

    Returns (t_start_s, t_stop_s, gamma), or None if the run has no flights.
    """
    df = flights[flights["settled"].astype(bool)] if "settled" in flights else flights
    if df.empty:
        return None
    steps = df.groupby("step")["gamma"].first()
    step = int((steps - gamma_target).abs().idxmin())
    sel = df[df["step"] == step].sort_values("t_takeoff_s")
    mid = sel.iloc[len(sel) // 2]
    t_start = float(mid["t_takeoff_s"]) - 0.02
    return t_start, t_start + duration_s, float(mid["gamma"])
