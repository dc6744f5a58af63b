"""Seed fig. 4: the accelerometer signal, and why the seed discarded it."""

from __future__ import annotations

import math

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from bouncelab.figures.style import DATA_COLOR, MODEL_COLOR
from bouncelab.flights.accel import gamma_scale_from_accel, harmonics_from_accel


def make(
    time_s: np.ndarray,
    accel_v: np.ndarray,
    residual_v: np.ndarray,
    continuity_landings_s: np.ndarray,
    comparison: pd.DataFrame,
    summary: dict,
    run_id: str,
    gamma: float | None = None,
    k_sigma: float = 6.0,
    gamma_by_step: pd.DataFrame | None = None,
):
    """Raw signal, residual after the drive fit, and the method's timing errors.

    Parameters
    ----------
    time_s, accel_v, residual_v : shape (n,), a short stretch: the accelerometer signal
        (V) and what remains after subtracting the fitted drive and harmonics.
    continuity_landings_s : landings found by the continuity method in the stretch (s).
    comparison, summary : from :func:`bouncelab.flights.accel.compare_methods` over the
        whole run (``diff_s`` per matched flight; shares and error percentiles).
    gamma_by_step : optional, the plate's Gamma the accelerometer reads per step
        (:func:`bouncelab.flights.accel.plate_gamma_by_step`; None without
        ``accel_v_per_g``): drawn beside the histogram as read over stated Gamma, with the
        Gamma scale of :func:`bouncelab.flights.accel.gamma_scale_from_accel`.
    Data: the summary numbers (share of continuity flights found, false share, median
    and 99th percentile absolute timing error in ms), and the Gamma scale with the
    harmonics read (:func:`bouncelab.flights.accel.harmonics_from_accel`) when given.
    """
    scale = gamma_scale_from_accel(gamma_by_step) if gamma_by_step is not None else None
    fig = plt.figure(figsize=(7.0, 6.4))
    if scale is not None:
        layout = [["signal", "signal"], ["residual", "residual"], ["hist", "gamma"]]
        mosaic = fig.subplot_mosaic(layout, width_ratios=[3, 2])
    else:
        mosaic = fig.subplot_mosaic([["signal"], ["residual"], ["hist"]])
    axes = [mosaic["signal"], mosaic["residual"], mosaic["hist"]]
    ms = (time_s - time_s[0]) * 1e3
    axes[0].plot(ms, accel_v, color=DATA_COLOR, lw=0.5, label="accelerometer")
    axes[0].plot(ms, accel_v - residual_v, color=MODEL_COLOR, lw=0.8, label="fitted drive")
    axes[0].set_ylabel("V")
    axes[0].legend(loc="upper right", fontsize=7)
    title = f"{run_id}: accelerometer on the plate"
    axes[0].set_title(title + (rf", $\Gamma$ = {gamma:g}" if gamma is not None else ""))
    sig = 1.4826 * float(np.median(np.abs(residual_v - np.median(residual_v))))
    axes[1].plot(ms, residual_v, color=DATA_COLOR, lw=0.5)
    for s in (-1, 1):
        axes[1].axhline(s * k_sigma * sig, color="0.5", ls=":", lw=0.7)
    for t in continuity_landings_s:
        axes[1].axvline((t - time_s[0]) * 1e3, color="#2ca02c", lw=0.7)
    axes[1].set_ylabel("residual (V)")
    axes[1].set_xlabel("time (ms); green: landings from the continuity circuit")
    axes[1].set_xlim(0, ms[-1])
    axes[0].set_xlim(0, ms[-1])
    diff_ms = comparison["diff_s"].dropna().to_numpy() * 1e3
    if diff_ms.size:
        lim = max(0.5, float(np.quantile(np.abs(diff_ms), 0.99)))
        axes[2].hist(np.clip(diff_ms, -lim, lim), bins=60, color=DATA_COLOR, alpha=0.8)
    axes[2].set_xlabel("accelerometer - continuity flight time (ms)")
    axes[2].set_ylabel("flights")
    if scale is not None:
        _draw_gamma(mosaic["gamma"], gamma_by_step, scale)
    fig.tight_layout()
    med = summary.get("median_abs_error_s")
    p99 = summary.get("p99_abs_error_s")
    data = {
        "run": run_id,
        "gamma": gamma,
        "n_continuity": summary.get("n_continuity"),
        "n_accel": summary.get("n_accel"),
        "share_found": summary.get("share_found"),
        "share_false": summary.get("share_false"),
        "median_abs_error_ms": med * 1e3 if med is not None else None,
        "p99_abs_error_ms": p99 * 1e3 if p99 is not None else None,
    }
    if med is not None and math.isfinite(med):
        data["summary"] = (
            f"the accelerometer method finds {100 * summary['share_found']:.1f} % of the "
            f"continuity flights ({100 * summary['share_false']:.1f} % of its flights match "
            f"none); median timing error {1e3 * med:.2f} ms, 99th percentile "
            f"{1e3 * p99:.2f} ms, against tens of microseconds for the continuity circuit."
        )
    else:
        data["summary"] = "the accelerometer method matched no flight."
    if scale is not None:
        data["gamma_scale"] = scale
        data["harmonics"] = harmonics_from_accel(gamma_by_step)
        data["summary"] += (
            f" The plate's Gamma it reads is {scale['s']:.4g} x the stated "
            f"[{scale['s_ci'][0]:.4g}, {scale['s_ci'][1]:.4g}] over {scale['n_steps']} steps"
            + "".join(
                f"; harmonic k = {h['k']}: a = {h['a']:.3g}, psi = {h['psi']:.3g}"
                for h in data["harmonics"]
            )
            + "."
        )
    return fig, data


def _draw_gamma(ax, by_step: pd.DataFrame, scale: dict) -> None:
    """Read over stated Gamma per step (error bars: two standard errors), and the Gamma
    ``scale`` with its interval."""
    use = by_step[by_step["gamma"] > 0]
    ratio = use["gamma_accel"] / use["gamma"]
    ax.errorbar(
        use["gamma"], ratio, yerr=2.0 * use["gamma_accel_se"] / use["gamma"], fmt="o",
        ms=3, color=DATA_COLOR, lw=0.8,
    )  # fmt: skip
    ax.axhspan(*scale["s_ci"], color=MODEL_COLOR, alpha=0.15, lw=0)
    ax.axhline(scale["s"], color=MODEL_COLOR, lw=0.8, label=f"s = {scale['s']:.4g}")
    ax.axhline(1.0, color="0.5", ls=":", lw=0.7)
    ax.set_xlabel(r"stated $\Gamma$")
    ax.set_ylabel(r"read / stated $\Gamma$")
    ax.legend(loc="best", fontsize=7)
