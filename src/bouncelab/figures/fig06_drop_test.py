"""Seed fig. 6: the drop test, its bounce sequence and the fitted friction and restitution."""

from __future__ import annotations

import numpy as np

from bouncelab.calibration import model_times
from bouncelab.figures.style import DATA_COLOR, MODEL_COLOR, new_figure


def make(calibration: dict, run_id: str):
    """Measured fall and bounce flight times against bounce number, with the fitted model.

    ``calibration``: the dict of :func:`bouncelab.calibration.calibrate_run` (with
    ``t_fall_s``, ``flights_s``, ``drop_height_m``, ``g_m_s2``). Bounce 0 is the fall
    from release. Data: mu, e and their intervals, the ratio of successive flights, the
    RMS residual (ms).
    """
    flights = np.asarray(calibration["flights_s"], dtype=float)
    measured = np.concatenate([[calibration["t_fall_s"]], flights])
    n = flights.size
    mu, e = calibration["mu"], calibration["restitution"]
    fitted = model_times(mu, e, calibration["drop_height_m"], n, calibration["g_m_s2"])
    idx = np.arange(n + 1)
    fig, ax = new_figure(width_in=6.0, height_in=3.6)
    ax.semilogy(idx, measured * 1e3, "o", color=DATA_COLOR, ms=4, label="measured")
    ax.semilogy(idx, fitted * 1e3, "-", color=MODEL_COLOR, lw=1, label="fitted model")
    ax.set_xlabel("bounce (0 = fall from release)")
    ax.set_ylabel("duration (ms)")
    ax.set_title(f"{run_id}: drop test")
    lo_mu, hi_mu = calibration["mu_ci"]
    lo_e, hi_e = calibration["restitution_ci"]
    ax.text(
        0.98,
        0.95,
        f"mu = {mu:.3f} [{lo_mu:.3f}, {hi_mu:.3f}]\ne = {e:.3f} [{lo_e:.3f}, {hi_e:.3f}]\n"
        f"ratio = {calibration['ratio']:.3f}",
        transform=ax.transAxes,
        ha="right",
        va="top",
        fontsize=8,
        family="DejaVu Sans Mono",
    )
    ax.legend(loc="lower left")
    fig.tight_layout()
    rms_ms = float(np.sqrt(np.mean((measured - fitted) ** 2)) * 1e3)
    data = {
        "run": run_id,
        "mu": mu,
        "mu_ci": [lo_mu, hi_mu],
        "restitution": e,
        "restitution_ci": [lo_e, hi_e],
        "ratio": calibration["ratio"],
        "n_bounces": calibration["n_bounces"],
        "t_fall_s": calibration["t_fall_s"],
        "rms_residual_ms": rms_ms,
        "summary": (
            f"{n} bounces fitted: mu = {mu:.3f} and e = {e:.3f} (the seed: about 0.29 and "
            f"0.515); successive flights shrink by {calibration['ratio']:.3f}; RMS residual "
            f"{rms_ms:.3f} ms."
        ),
    }
    return fig, data
