"""Seed fig. 5: a stretch of the continuity signal with the detected takeoffs and landings."""

from __future__ import annotations

import numpy as np
import pandas as pd

from bouncelab.figures.style import DATA_COLOR, new_figure


def make(
    time_s: np.ndarray,
    volts: np.ndarray,
    flights: pd.DataFrame,
    run_id: str,
    gamma: float | None = None,
    levels: tuple[float, float] | None = None,
):
    """The signal (volts against milliseconds) with each detected flight shaded.

    ``time_s``, ``volts``: shape (n,), the stretch to show. ``flights``: rows with
    ``t_takeoff_s`` and ``t_landing_s`` (only those inside the stretch are drawn).
    ``levels``: optional (contact, open) levels in volts, drawn as dotted lines.
    Data: the stretch, the number of flights shown and their durations (ms).
    """
    t0 = float(time_s[0])
    t1 = float(time_s[-1])
    inside = flights[(flights["t_takeoff_s"] >= t0) & (flights["t_landing_s"] <= t1)]
    fig, ax = new_figure(width_in=7.0, height_in=3.0)
    ms = (time_s - t0) * 1e3
    ax.plot(ms, volts, color=DATA_COLOR, lw=0.7, drawstyle="steps-mid")
    for a, b in zip(inside["t_takeoff_s"], inside["t_landing_s"], strict=True):
        ax.axvspan((a - t0) * 1e3, (b - t0) * 1e3, color="#2ca02c", alpha=0.15, lw=0)
        ax.axvline((a - t0) * 1e3, color="#2ca02c", lw=0.6)
        ax.axvline((b - t0) * 1e3, color="#d62728", lw=0.6)
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
    fig.tight_layout()
    durations = (inside["t_landing_s"] - inside["t_takeoff_s"]).to_numpy() * 1e3
    data = {
        "run": run_id,
        "t_start_s": t0,
        "t_stop_s": t1,
        "gamma": gamma,
        "n_flights": int(len(inside)),
        "flight_ms": durations,
        "summary": (
            f"{len(inside)} flights in {1e3 * (t1 - t0):.0f} ms"
            + (f" at Gamma = {gamma:g}" if gamma is not None else "")
            + (f", {durations.min():.2f} to {durations.max():.2f} ms long." if len(inside) else ".")
        ),
    }
    return fig, data


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
