"""A plain-Python reference of the ideal model, written the way the seed's MatLab code works.

Each flight: scan the relative height in fixed phase steps until it changes sign, then
refine the bracket with :func:`scipy.optimize.brentq`.  Slow, and a fixed-step scan can
step over a graze; it exists as the speed baseline of ``benchmarks/bench_physics.py``
and as an independent cross-check of the compiled kernels on ordinary flights.
"""

from __future__ import annotations

import math

from scipy.optimize import brentq

TWO_PI = 2.0 * math.pi


def relative_height(t: float, gamma: float, phi0: float) -> float:
    """Ideal ball that left the plate at ``phi0`` with the plate's velocity, ``t`` later.

    ``Gamma sin(phi0) + Gamma cos(phi0) t - t^2/2 - Gamma sin(phi0 + t)`` (DESIGN.md;
    the seed's eq. 8 is garbled).
    """
    return (
        gamma * math.sin(phi0) + gamma * math.cos(phi0) * t - 0.5 * t * t
        - gamma * math.sin(phi0 + t)
    )  # fmt: skip


def flight_time(gamma: float, phi0: float, dt: float = 1e-2) -> float:
    """First sign change of :func:`relative_height` found by a scan of step ``dt``, then brentq."""
    t = dt
    while relative_height(t, gamma, phi0) > 0.0:
        t += dt
    return brentq(relative_height, t - dt, t, args=(gamma, phi0), xtol=1e-13, rtol=1e-15)


def reference_flights(gamma: float, n_flights: int, n_skip: int = 0, dt: float = 1e-2):
    """Flight times ``[T...]`` (rad) of the ideal ball from rest at phase 0; ``[]`` if Gamma <= 1.

    A landing in the bouncing region (``Gamma sin(phi) > 1``) takes off at once, a
    landing below the takeoff line rides to the next ``arcsin(1/Gamma)``.
    """
    if gamma <= 1.0:
        return []
    phi_line = math.asin(1.0 / gamma)
    phi = phi_line
    out = []
    for i in range(n_skip + n_flights):
        t = flight_time(gamma, phi, dt)
        if i >= n_skip:
            out.append(t)
        phi = (phi + t) % TWO_PI
        if not gamma * math.sin(phi) > 1.0:
            phi = phi_line if phi < phi_line else phi_line + TWO_PI
    return out
