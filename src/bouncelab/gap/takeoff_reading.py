"""The plate's drive harmonic and the guide's friction read off the takeoff phases.

A body that rides the plate leaves it where the plate's downward acceleration first
exceeds gravity's, raised by friction while the plate moves up and lowered while it
moves down (:func:`bouncelab.physics.kernels.takeoff_ok`). With the plate
``chi_p = (Gamma g / w^2) [sin(phi) + a sin(k phi + psi)]`` the body leaves at the first
phase after its ride began where

    Gamma [sin(phi) + a k^2 sin(k phi + psi)] >= 1 + mu sign(cos(phi) + a k cos(k phi + psi)).

So each Gamma step's takeoff phase after a ride is one sample of the plate's acceleration
waveform, and a sweep's worth of them reads ``k, a, psi`` and ``mu`` with no simulation
(restitution does not enter: it decides whether the body rides, not where it leaves).
What this reading does not see: a Gamma miscalibration ``s`` is nearly the same as a
change of ``mu`` here, and the armature's ring-down moves the plate during a ride, so
on a run with the armature the reading is not the plate's drive (docs/diagnosis.md,
"The takeoff reading").

Where a harmonic stands out (:func:`seen_harmonic`), every round's fit of a model with
the harmonic starts from the reading where it does better than the fit's own start
(:func:`bouncelab.gap.select.read_starts`): the fits' searches miss the harmonic's
narrow basin on some runs. And a harmonic fitted to the flight times that fits the
takeoffs much worse than no harmonic at all is refused in its round
(:func:`harmonic_refuted`): it stands in for another effect. The reading is measured
beside the truth of the independent generator in ``benchmarks/bench_takeoff_reading.py``
(docs/diagnosis-log.md, sessions 52-54).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
from scipy.optimize import minimize

from bouncelab.gap.features import circular_mean, wrap_angle
from bouncelab.gap.fit import K_CHOICES

#: The harmonics read: the whole-number ``k`` of :data:`bouncelab.gap.fit.K_CHOICES`. Why
#: not 0.5, 1.5, 2.5: their plate repeats every other cycle, and a takeoff phase taken
#: modulo one cycle cannot say which of the two cycles it is in (on the independent null
#: run a k 0.5 of a 0.03 fitted the takeoffs 3.6 times better than no harmonic).
READ_K = tuple(k for k in K_CHOICES if float(k).is_integer())
#: A ride is a contact of at least this share of a drive cycle before the takeoff: a body
#: at rest on the plate, not an impact's contact or the chatter that ends in a ride.
MIN_RIDE_CYCLES = 0.15
#: Steps with fewer ride takeoffs than this are not read.
MIN_TAKEOFFS = 5
#: A step is read only when its ride takeoffs gather at one phase: the length of their mean
#: unit phasor is at least this (0.99: a spread of about 0.14 rad). Why: a step between two
#: regimes leaves from two places, and their mean is neither (independent
#: ``friction_harmonic_g0-8`` at Gamma 1.6: takeoffs at 0.3 and 1.7 rad, mean 0.97).
MIN_RESULTANT = 0.99
#: Fewer steps read than this: nothing is fitted (four parameters from the takeoffs of a
#: few steps say nothing: independent ``vibration``, 3 steps, read a 0.32 at k 3).
MIN_STEPS = 8
#: ``mu`` of the harmonic fits' grid of starts.
MU_START = 0.1
#: Starting grid of ``mu`` for the fit without a harmonic.
MU_STARTS = np.linspace(-0.5, 1.0, 76)
#: Phases (rad) at which a predicted takeoff is searched after a ride's start: one cycle,
#: the crossing placed by linear interpolation between grid points.
PHASE_GRID = np.linspace(0.0, 2.0 * math.pi, 361)
#: A harmonic "seen": its share of the plate's acceleration ``a k^2`` at least
#: :data:`SEEN_AK2` and its fit's rms :data:`SEEN_RATIO` times below the fit without one.
#: Measured on the 59 independent cases (session 52): 8 of 8 whole-k harmonics seen, 0 of
#: 40 other library cases, 1 effect outside the library (a sensor delay of 2 ms); on an
#: armature run the ring-down stands in for a harmonic (``restitution_feedback``: k 2 of
#: a k^2 0.20 at a ratio of 6).
SEEN_AK2 = 0.03
SEEN_RATIO = 10.0
#: A fitted harmonic the takeoffs refuse: with ``mu`` refitted it fits them this many times
#: worse (rms) than no harmonic at all (:func:`harmonic_refuted`). Measured on the
#: independent cases' recorded fits (session 54): the true whole-k harmonics 0.01-0.35 of
#: the plain fit's rms (a Gamma miscalibration beside one the 0.35), the k-2 harmonic
#: selected in place of ``friction_feedback``'s armature (a k^2 0.10) 6.8.
REFUTED_RATIO = 2.0
#: Starting grid of the harmonic's strength ``a k^2`` (its share of the plate's
#: acceleration) and its phase.
A_K2_STARTS = np.linspace(0.02, 0.4, 10)
PSI_STARTS = np.linspace(0.0, 2.0 * math.pi, 24, endpoint=False)


def ride_takeoffs(flights: pd.DataFrame, drive_hz: float) -> pd.DataFrame:
    """Per Gamma step, where rides began and where the body left the plate.

    ``flights``: a flight table (CONTRACTS.md section 3: ``step``, ``gamma``,
    ``t_takeoff_s``, ``t_landing_s``, ``phi_takeoff`` in rad), recording order.
    ``drive_hz``: the drive frequency (Hz).

    A ride is the contact between a landing and the next takeoff in the same step, at
    least :data:`MIN_RIDE_CYCLES` of a cycle long, whose takeoff has a phase. Returns one
    row per step with at least :data:`MIN_TAKEOFFS` rides whose takeoff phases gather
    (:data:`MIN_RESULTANT`):
    ``step``, ``gamma``, ``phi_takeoff`` (rad in [0, 2 pi), the circular mean),
    ``phi_start`` (rad in [0, 2 pi), the circular mean of the rides' starts), ``n``.
    """
    f = flights
    same = f["step"].to_numpy()[1:] == f["step"].to_numpy()[:-1]
    contact = (
        f["t_takeoff_s"].to_numpy(dtype=float)[1:] - f["t_landing_s"].to_numpy(dtype=float)[:-1]
    )
    # no phase without a drive channel (CONTRACTS.md section 3: NaN): nothing to read
    phased = np.isfinite(f["phi_takeoff"].to_numpy(dtype=float))[1:]
    ride = same & phased & (contact >= MIN_RIDE_CYCLES / float(drive_hz))
    rides = f.iloc[1:][ride].assign(contact_s=contact[ride])
    rows = []
    for step, g in rides.groupby("step", sort=True):
        if len(g) < MIN_TAKEOFFS:
            continue
        phi = g["phi_takeoff"].to_numpy(dtype=float)
        takeoff, resultant = circular_mean(phi)
        if resultant < MIN_RESULTANT:
            continue
        start, _r = circular_mean(phi - 2.0 * math.pi * float(drive_hz) * g["contact_s"].to_numpy())
        rows.append(
            {
                "step": int(step),
                "gamma": float(g["gamma"].iloc[0]),
                "phi_takeoff": takeoff % (2.0 * math.pi),
                "phi_start": start % (2.0 * math.pi),
                "n": int(len(g)),
            }
        )
    return pd.DataFrame(rows, columns=["step", "gamma", "phi_takeoff", "phi_start", "n"])


def predicted_takeoff(gamma, phi_start, k: float, a: float, psi: float, mu: float):
    """First phase (rad, ``>= phi_start``, within one cycle of it) where a body riding from
    ``phi_start`` leaves the plate ``sin(phi) + a sin(k phi + psi)`` at ``gamma``, with
    guide friction ``mu`` (the condition of the module docstring). ``gamma``,
    ``phi_start``: arrays of shape (S,). NaN where it does not leave within the cycle."""
    gamma = np.asarray(gamma, dtype=float)
    p = np.asarray(phi_start, dtype=float)[:, None] + PHASE_GRID[None, :]
    vel = np.cos(p) + a * k * np.cos(k * p + psi)
    margin = gamma[:, None] * (np.sin(p) + a * k * k * np.sin(k * p + psi))
    margin -= 1.0 + mu * np.sign(vel)
    leaves = margin >= 0.0
    j = np.argmax(leaves, axis=1)
    rows = np.arange(j.size)
    left = leaves[rows, j]
    before = np.maximum(j - 1, 0)
    m0, m1 = margin[rows, before], margin[rows, j]
    share = np.where(j > 0, -m0 / np.where(m1 > m0, m1 - m0, 1.0), 0.0)
    phase = p[rows, before] + share * (PHASE_GRID[1] - PHASE_GRID[0])
    return np.where(left, phase, np.nan)


def _residuals(points: pd.DataFrame, k: float, a: float, psi: float, mu: float) -> np.ndarray:
    """Measured minus predicted takeoff phase per step (rad, wrapped to (-pi, pi]); a step
    the prediction never leaves counts as 1 rad."""
    pred = predicted_takeoff(points["gamma"], points["phi_start"], k, a, psi, mu)
    return np.nan_to_num(wrap_angle(points["phi_takeoff"].to_numpy() - pred), nan=1.0)


def _rms(points, k, a, psi, mu) -> float:
    return float(np.sqrt(np.mean(_residuals(points, k, a, psi, mu) ** 2)))


def fit_mu(points: pd.DataFrame, k: float, a: float, psi: float) -> tuple[float, float]:
    """``(mu, rms)``: the friction that best fits the takeoff phases of ``points``
    (:func:`ride_takeoffs`) with the harmonic ``k, a, psi`` held, and the rms (rad) there.
    The best of :data:`MU_STARTS`, then Nelder-Mead within ``[-0.5, 1]``.

    Why the grid first: a step the plate never releases counts 1 rad, and those plateaus
    stop a simplex started far off (independent ``gamma_scale_40hz_short_steps``: stuck at
    61 times the harmonic fit's rms)."""
    _r, mu0 = min((_rms(points, k, a, psi, mu), mu) for mu in MU_STARTS)
    sol = minimize(
        lambda x: _rms(points, k, a, psi, x[0]),
        [mu0],
        method="Nelder-Mead",
        bounds=[(-0.5, 1.0)],
        options={"xatol": 1e-5, "fatol": 1e-9},
    )
    return float(sol.x[0]), float(sol.fun)


def read_takeoffs(points: pd.DataFrame, k_choices=READ_K) -> dict:
    """Fit the takeoff condition to the steps of :func:`ride_takeoffs`.

    Without a harmonic, ``mu`` alone (the best of :data:`MU_STARTS`, then Nelder-Mead);
    with one, for each ``k`` of ``k_choices``: ``a, psi, mu`` from the best of a grid of
    starts (:data:`A_K2_STARTS` x :data:`PSI_STARTS` at ``mu`` :data:`MU_START`), refined
    by Nelder-Mead within ``a`` in [0, 0.5], ``mu`` in [-0.5, 1]; where that ends worse
    than no harmonic, no harmonic (``a`` 0). Deterministic.

    Returns ``{"n_steps", "plain": {"mu", "rms_rad"}, "by_k": [{"k", "a", "psi", "mu",
    "rms_rad"}, ...], "best": the entry of by_k with the least rms}``; with fewer than
    :data:`MIN_STEPS` steps ``{"n_steps": n}`` alone (nothing to read).
    """
    n = len(points)
    if n < MIN_STEPS:
        return {"n_steps": n}
    mu_plain, rms_plain = fit_mu(points, 1.0, 0.0, 0.0)
    by_k = []
    for k in k_choices:
        starts = [
            (_rms(points, k, ak2 / k**2, psi, MU_START), ak2 / k**2, psi, MU_START)
            for ak2 in A_K2_STARTS
            for psi in PSI_STARTS
        ]
        _r, a0, psi0, mu0 = min(starts)
        sol = minimize(
            lambda x, k=k: _rms(points, k, x[0], x[1], x[2]),
            [a0, psi0, mu0],
            method="Nelder-Mead",
            bounds=[(0.0, 0.5), (-4.0 * math.pi, 6.0 * math.pi), (-0.5, 1.0)],
            options={"xatol": 1e-5, "fatol": 1e-9, "maxiter": 800},
        )
        a, psi, mu = (float(v) for v in sol.x)
        if sol.fun > rms_plain:
            # a simplex stuck on a plateau (a step the plate never releases counts 1 rad):
            # no harmonic at all fits better (independent restitution_gamma_scale: 8 times
            # the plain fit's rms); a start there instead reads the true harmonics worse
            # (6 of 11 independent harmonics' a within 10 % for 7)
            a, psi, mu, sol.fun = 0.0, 0.0, mu_plain, rms_plain
        by_k.append(
            {
                "k": float(k),
                "a": a,
                "psi": psi % (2.0 * math.pi),
                "mu": mu,
                "rms_rad": float(sol.fun),
            }
        )
    return {
        "n_steps": n,
        "plain": {"mu": mu_plain, "rms_rad": rms_plain},
        "by_k": by_k,
        "best": min(by_k, key=lambda r: r["rms_rad"]),
    }


def seen_harmonic(reading: dict) -> dict | None:
    """The best harmonic of a :func:`read_takeoffs` result where it stands out
    (:data:`SEEN_AK2`, :data:`SEEN_RATIO`): ``{"k", "a", "psi", "mu"}``; else None."""
    best = reading.get("best")
    if not best or best["a"] * best["k"] ** 2 < SEEN_AK2:
        return None
    if reading["plain"]["rms_rad"] < SEEN_RATIO * best["rms_rad"]:
        return None
    return {name: float(best[name]) for name in ("k", "a", "psi", "mu")}


def takeoff_rms(points: pd.DataFrame, k: float, a: float, psi: float) -> float:
    """rms (rad) of the takeoff phases of ``points`` (:func:`ride_takeoffs`) about the
    prediction of a plate with the harmonic ``k, a, psi``, with ``mu`` refitted
    (:func:`fit_mu`)."""
    return fit_mu(points, k, a, psi)[1]


def harmonic_refuted(points: pd.DataFrame, reading: dict, k: float, a: float, psi: float):
    """Whether the takeoff phases refuse a fitted harmonic ``k, a, psi``: it fits them
    :data:`REFUTED_RATIO` times worse than no harmonic (:func:`takeoff_rms` against the
    ``plain`` fit of ``reading``, :func:`read_takeoffs` of ``points``). Returns
    ``{"k", "a", "psi", "rms_rad", "plain_rms_rad"}`` where it does; None where it does
    not, where nothing was read (fewer than :data:`MIN_STEPS` steps), and for a ``k`` the
    reading cannot judge (not in :data:`READ_K`).

    Why: a harmonic fitted to the flight times can stand in for another effect (the
    independent ``friction_feedback``: a k-2 harmonic of a k^2 0.10 in the armature's
    place, explained at 0.45 floors), but a plate that moved so would move every ride's
    takeoff, and the takeoffs show no such move.
    """
    if "plain" not in reading or float(k) not in READ_K:
        return None
    plain = float(reading["plain"]["rms_rad"])
    rms = takeoff_rms(points, float(k), float(a), float(psi))
    if rms <= REFUTED_RATIO * plain:
        return None
    return {"k": float(k), "a": float(a), "psi": float(psi), "rms_rad": rms, "plain_rms_rad": plain}
