"""Shared helpers of the rig tests: small configs, short recordings."""

from __future__ import annotations

import math

from bouncelab.rig import parse_rig_config


def quiet_config(**over) -> dict:
    """A rigid-shaker, noiseless sweep config; ``over`` merges into the top-level blocks."""
    raw = {
        "kind": "sweep",
        "seed": 0,
        "shaker": {"feedback": False},
        "sensors": {
            "continuity": {"noise_v": 0.0, "drift_v": 0.0},
            "drive": {"noise_v": 0.0},
        },
    }
    for key, val in over.items():
        if isinstance(val, dict) and isinstance(raw.get(key), dict):
            raw[key] = {**raw[key], **val}
        else:
            raw[key] = val
    return parse_rig_config(raw)


def ideal_flight_from_rest(gamma: float) -> float:
    """Completely inelastic ball from rest on the plate: flight T (rad), DESIGN.md section 1.

    First root T > 0 of Gamma sin p0 + Gamma cos p0 T - T^2/2 - Gamma sin(p0 + T) = 0,
    p0 = arcsin(1/Gamma); bracketed by a fine scan, then brentq.
    """
    from scipy.optimize import brentq

    p0 = math.asin(1.0 / gamma)

    def f(t):
        return (
            gamma * math.sin(p0) + gamma * math.cos(p0) * t - t * t / 2 - gamma * math.sin(p0 + t)
        )

    t_prev, f_prev = 1e-6, f(1e-6)
    for i in range(1, 20001):
        t = i * 1e-3
        ft = f(t)
        if f_prev > 0 >= ft:
            return brentq(f, t_prev, t, xtol=1e-12)
        t_prev, f_prev = t, ft
    raise AssertionError("no root")
