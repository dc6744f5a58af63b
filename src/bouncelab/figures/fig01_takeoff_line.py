"""Seed fig. 1: plate motion, takeoff line, sticking and bouncing regions, a trajectory."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from bouncelab.figures.style import DATA_COLOR, MODEL_COLOR, new_figure


def ball_height(phi, phi0: float, gamma: float) -> np.ndarray:
    """Height of the completely inelastic ball in flight (nondimensional), DESIGN.md §1.

    It leaves the plate at phase ``phi0`` with the plate's position ``Gamma sin phi0`` and
    velocity ``Gamma cos phi0`` under unit gravity.
    """
    s = np.asarray(phi) - phi0
    return gamma * math.sin(phi0) + gamma * math.cos(phi0) * s - 0.5 * s * s


def apex_height(phi0: float, gamma: float) -> float:
    """Highest point of a flight leaving the plate at ``phi0``: chi0 + v0^2 / 2 (unit gravity)."""
    v0 = max(0.0, gamma * math.cos(phi0))
    return gamma * math.sin(phi0) + 0.5 * v0 * v0


def make(flights: pd.DataFrame, gamma: float, cycles: float = 3.0):
    """Plate, takeoff line, regions and the ball's flights over the first ``cycles``.

    ``flights``: consecutive ideal-model flights from rest at this Gamma, with absolute
    takeoff phase ``t_takeoff`` (rad) and duration ``T`` (rad). Between flights the ball
    rides the plate. Data: first takeoff phase and its reference arcsin(1/Gamma), the
    flight times shown.
    """
    phi = np.linspace(0.0, 2.0 * math.pi * cycles, 2000)
    plate = gamma * np.sin(phi)
    fig, ax = new_figure(width_in=7.0, height_in=3.4)
    top = gamma + 1.0
    ax.axhspan(1.0, top * 3, color="#2ca02c", alpha=0.08, lw=0)
    ax.axhspan(-gamma * 1.2, 1.0, color="#1f77b4", alpha=0.06, lw=0)
    ax.axhline(1.0, color="#2ca02c", lw=1.0, ls="--", label=r"takeoff line $\Gamma\sin\varphi = 1$")
    ax.plot(phi, plate, color=DATA_COLOR, lw=1.2, label=r"plate $\chi_p = \Gamma\sin\varphi$")
    end = phi[-1]
    shown = []
    ball_label = "ball"
    for t0, T in zip(flights["t_takeoff"].to_numpy(), flights["T"].to_numpy(), strict=True):
        if t0 > end:
            break
        p0 = math.fmod(t0, 2.0 * math.pi)
        s = np.linspace(t0, min(t0 + T, end), 200)
        ax.plot(s, ball_height(s - t0 + p0, p0, gamma), color=MODEL_COLOR, lw=1.2, label=ball_label)
        ball_label = None
        shown.append({"t_takeoff": float(t0), "T": float(T)})
    ax.text(0.05, 0.93, "bouncing region", transform=ax.transAxes, color="#2ca02c", fontsize=8)
    ax.text(0.05, 0.04, "sticking region", transform=ax.transAxes, color="#1f77b4", fontsize=8)
    ax.set_xlim(0, end)
    apexes = [apex_height(math.fmod(f["t_takeoff"], 2 * math.pi), gamma) for f in shown]
    ymax = max([top, *apexes])
    ax.set_ylim(-gamma * 1.15, ymax * 1.1)
    ax.set_xlabel(r"phase $\varphi = \omega t$ (rad)")
    ax.set_ylabel(r"height $\chi = x\omega^2/g$")
    ax.set_title(rf"Completely inelastic ball, $\Gamma$ = {gamma:g}")
    ax.legend(loc="lower right", fontsize=7)
    fig.tight_layout()
    first = (
        math.fmod(float(flights["t_takeoff"].iloc[0]), 2 * math.pi) if len(flights) else math.nan
    )
    data = {
        "gamma": gamma,
        "first_takeoff_phase": first,
        "first_takeoff_reference": math.asin(1.0 / gamma) if gamma >= 1 else None,
        "flights": shown,
        "summary": (
            f"at Gamma = {gamma:g} the ball first leaves the plate at phi = {first:.5f} rad "
            f"(arcsin(1/Gamma) = {math.asin(1 / gamma):.5f}) and flies for "
            f"{shown[0]['T'] / (2 * math.pi):.4f} drive periods."
            if shown and gamma >= 1
            else "no flight."
        ),
    }
    return fig, data
