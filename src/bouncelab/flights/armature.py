"""The shaker's armature read from a plate accelerometer: its ring-down after impacts.

The flight times leave the armature's damping ratio loose (docs/diagnosis.md, section 5:
25-400 % off on the blind combinations); an accelerometer on the plate sees the armature
ring after every impact, as a drop test sees friction and restitution.

Model (the virtual rig's, docs/rig.md, and the ``feedback`` effect's, CONTRACTS.md
section 5): the plate is the commanded motion plus the armature's deflection ``y``,
``M y'' + c y' + k y = -F`` with ``F`` the body's contact force, natural frequency
``f_a = sqrt(k / M) / 2 pi`` and damping ratio ``zeta = c / (2 sqrt(k M))``. An impact
kicks ``y'``; a body riding the plate loads it with ``m (g + a_plate)`` (plus the guide's
friction, ``+- mu m g``). So the acceleration of one Gamma step is, by least squares:

- fixed columns: the drive, its harmonics and mains hum
  (:func:`bouncelab.flights.accel.drive_basis`), and per landing the impact's spike as
  the low-pass shapes it (free amplitude: a sampled spike is caught or missed by luck);
- columns of ``(f_a, zeta)``: the armature's free response from the step's start, its
  ring after a velocity kick at each landing (free amplitude: each impact's speed is not
  known here), and its response to the riding load and to the friction's sign.

The channel is low-passed (zero phase) at :data:`LOWPASS_DRIVES` drive frequencies and
decimated. Steps with stated Gamma > 1 and two to :data:`MAX_LANDINGS_PER_CYCLE` landings
a cycle are used, at most :data:`MAX_STEPS` spread over Gamma. The fixed columns are
projected out once per step (variable projection), and the mean square residual over the
steps is minimised over ``(log f_a, log zeta)``: a grid of ``f_a``, then (unless the
grid's best is below :data:`GRID_STOP_RATIO`) Nelder-Mead, twice (:data:`PASSES`: the
second loads the armature with the plate's whole acceleration, its own included, as a
riding body follows it). The armature is **read** when its
columns lower the residual rms :data:`MIN_RMS_RATIO` times or more. ``mass_ratio`` is
not read (the kicks are free). An armature that the impacts ring in step with the drive
(period-1 bouncing, a slow or damped ring) is not read: its response is the drive's
harmonics. Accuracy on the virtual rig: ``benchmarks/bench_accel_armature.py``.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
from scipy.optimize import minimize
from scipy.signal import butter, lfilter, sosfiltfilt

from bouncelab.flights.accel import accel_in_g, drive_basis

G_M_S2 = 9.80665
LOWPASS_DRIVES = 6.0  # low-pass corner in drive frequencies: the ring (below it) stays
SAMPLES_PER_CORNER = 3.0  # decimated samples per corner period
N_HARMONICS = 5
HUM_HZ = (50.0,)
#: The armature's natural frequency is searched over these multiples of the drive (a
#: shaker's suspension resonance sits below the drive in the seed's range, above it at
#: low drive frequencies).
F_RATIO_GRID = np.exp(np.linspace(math.log(0.2), math.log(3.0), 17))
F_RATIO_BOUNDS = (0.05, 5.0)
ZETA_START = 0.05
ZETA_BOUNDS = (0.002, 0.9)
#: Steps used at most (the ones with the most landings, in step order): each step adds
#: as much evidence of the same two numbers, and the time grows with them.
MAX_STEPS = 40
#: Steps with more landings per drive cycle are left out (chatter, random vibration).
MAX_LANDINGS_PER_CYCLE = 3.0
#: Least rms ratio (fixed columns alone / with the armature) that reads an armature. On
#: the virtual rig (``bench_accel_armature.py``): 1.05-1.46 over 42 rigid-shaker runs,
#: 2.66-3.81 over the 9 armatures read.
MIN_RMS_RATIO = 2.0
#: Below this ratio at the grid's best (zeta 0.05) the search stops there, not read: the
#: searches after the grid gained at most a factor 1.31 on the rig's runs.
GRID_STOP_RATIO = 1.4
#: Fits of ``(f_a, zeta)``: the second loads the armature with the first's own motion.
PASSES = 2
#: Nelder-Mead's tolerance on ``log f_a`` and ``log zeta`` (1 %) and its evaluations a pass.
XATOL = 0.01
MAX_EVALS = 40


def ring_segments(accel_m_s2, fs, steps, flights, drive_hz, time_s=None, max_steps=MAX_STEPS):
    """Per Gamma step (stated Gamma > 1, two landings to :data:`MAX_LANDINGS_PER_CYCLE` a
    cycle): the low-passed, decimated acceleration and what the fit needs of the step.

    Parameters
    ----------
    accel_m_s2 : (n,) plate acceleration, m/s^2.  fs : Hz.
    steps : DataFrame ``step, gamma, t_start_s, t_end_s``.
    flights : DataFrame with ``t_takeoff_s``, ``t_landing_s`` (s; the continuity's flights).
    drive_hz : Hz.  time_s : (n,) or None (then ``index / fs``).
    max_steps : steps kept at most, spread over the run's Gamma (:data:`MAX_STEPS`).

    Returns
    -------
    list of dicts, one per step, in step order: ``t`` (m,) s from the step's start,
    ``a`` (m,) m/s^2 and ``a_perp`` (m,) its part outside the fixed columns, ``land``
    (L,) landing times from the step's start, ``contact`` (m,) bool (the body on the
    plate), ``fixed_q`` (m, k) orthonormal basis of the fixed columns, ``a_plate`` and
    ``v_sign`` (m,) the plate's acceleration as the drive columns fit it (m/s^2) and the
    sign of its velocity.
    """
    accel = np.asarray(accel_m_s2, dtype=np.float64)
    fc = min(LOWPASS_DRIVES * drive_hz, 0.2 * fs)
    sos = butter(4, fc, fs=fs, output="sos")
    af = sosfiltfilt(sos, accel)
    q = max(1, int(fs // (SAMPLES_PER_CORNER * fc)))
    t_all = np.arange(af.size) / fs if time_s is None else np.asarray(time_s, dtype=np.float64)
    half = int(math.ceil(4.0 / fc * fs))
    unit = np.zeros(2 * half + 1)
    unit[half] = fs
    spike = sosfiltfilt(sos, unit)  # the low-pass's response to a unit-area impulse, 1/s
    lag = (np.arange(spike.size) - half) / fs
    land_all = np.sort(flights["t_landing_s"].to_numpy(dtype=np.float64))
    take_all = np.sort(flights["t_takeoff_s"].to_numpy(dtype=np.float64))
    found = []
    for st in steps.itertuples(index=False):
        if st.gamma <= 1.0:
            continue
        i0, i1 = np.searchsorted(t_all, [st.t_start_s, st.t_end_s])
        land = land_all[(land_all >= st.t_start_s) & (land_all < st.t_end_s)]
        idx = np.arange(i0, i1, q)
        if idx.size < 64 or land.size < 2:
            continue
        if land.size > MAX_LANDINGS_PER_CYCLE * (st.t_end_s - st.t_start_s) * drive_hz:
            continue  # chatter: the rings of so many free kicks leave no shape to read
        found.append((land.size, st, idx, land))
    if len(found) > max_steps:  # spread over the run's Gamma range, both ends kept
        keep = np.unique(np.round(np.linspace(0, len(found) - 1, max_steps)).astype(int))
        found = [found[i] for i in keep]
    out = []
    for _n, st, idx, land in found:
        t = t_all[idx]
        nxt = np.minimum(np.searchsorted(take_all, land), take_all.size - 1)
        take = np.where(take_all[nxt] > land, take_all[nxt], st.t_end_s)
        edges = np.zeros(t.size + 1, dtype=np.int64)
        np.add.at(edges, np.searchsorted(t, land), 1)
        np.add.at(edges, np.searchsorted(t, take), -1)
        contact = np.cumsum(edges)[: t.size] > 0
        t0 = t[0]
        t, land = t - t0, land - t0
        a = af[idx]
        drive = drive_basis(t, drive_hz, N_HARMONICS, HUM_HZ)
        coef, *_ = np.linalg.lstsq(drive, a, rcond=None)
        w = 2.0 * math.pi * drive_hz
        a_plate = drive[:, 1 : 1 + 2 * N_HARMONICS] @ coef[1 : 1 + 2 * N_HARMONICS]
        v_plate = sum(
            (-coef[2 * h - 1] * np.cos(h * w * t) + coef[2 * h] * np.sin(h * w * t)) / (h * w)
            for h in range(1, N_HARMONICS + 1)
        )
        spikes = np.interp(t[:, None] - land[None, :], lag, spike, left=0.0, right=0.0)
        fixed_q, _ = np.linalg.qr(np.concatenate([drive, spikes], axis=1))
        out.append(
            {
                "t": t,
                "a": a,
                "a_perp": a - fixed_q @ (fixed_q.T @ a),
                "land": land,
                "contact": contact,
                "fixed_q": fixed_q,
                "a_plate": a_plate,
                "v_sign": np.sign(v_plate),
            }
        )
    return out


def armature_columns(seg: dict, fn_hz: float, zeta: float, arm=None) -> np.ndarray:
    """The columns of one step that depend on the armature (m, 4 + L): its free response
    from the step's start (2), its ring after a unit velocity kick at each landing (L),
    and its response (acceleration per unit force over mass) to the riding load
    ``g + a_plate`` and to the guide's friction ``g sign(v_plate)`` while in contact.
    ``arm``: (m,) the armature's own acceleration (m/s^2), added to the commanded
    ``a_plate`` in the load (a riding body follows the whole plate)."""
    t, land = seg["t"], seg["land"]
    wn = 2.0 * math.pi * fn_hz
    al = zeta * wn
    wd = wn * math.sqrt(max(1.0 - zeta * zeta, 1e-12))
    ex = np.exp(-al * t)
    free = [ex * np.cos(wd * t), ex * np.sin(wd * t)]
    tau = t[:, None] - land[None, :]
    tp = np.maximum(tau, 0.0)
    e = np.exp(-al * tp)
    s, c = np.sin(wd * tp), np.cos(wd * tp)
    # y'' after y' jumps by 1 at tau = 0 (y = e^{-al tau} sin(wd tau) / wd)
    kicks = np.where(tau >= 0.0, -wn * wn * e * s / wd - 2.0 * al * e * (c - al / wd * s), 0.0)
    # y'' per unit force over mass, -s^2 / (s^2 + 2 al s + wn^2), by the bilinear
    # transform s = k (1 - 1/z) / (1 + 1/z), k = 2 / dt (scipy.signal.bilinear's)
    k = 2.0 / float(t[1] - t[0])
    a0 = k * k + 2.0 * al * k + wn * wn
    b = np.array([-k * k, 2.0 * k * k, -k * k]) / a0
    a = np.array([1.0, (2.0 * wn * wn - 2.0 * k * k) / a0, (k * k - 2.0 * al * k + wn * wn) / a0])
    a_plate = seg["a_plate"] if arm is None else seg["a_plate"] + arm
    load = lfilter(b, a, np.where(seg["contact"], G_M_S2 + a_plate, 0.0))
    pole = lfilter(b, a, np.where(seg["contact"], G_M_S2 * seg["v_sign"], 0.0))
    return np.concatenate([np.stack(free, axis=1), kicks, load[:, None], pole[:, None]], axis=1)


def _step_fit(seg: dict, fn_hz: float, zeta: float, arm: np.ndarray | None, motion=False):
    """One step's least squares with the armature's columns: the residual's sum of
    squares and, with ``motion``, the fitted armature acceleration (m,), m/s^2 (else
    None). By variable projection:
    the fixed columns are projected out of both sides, and the armature's coefficients
    of the joint fit are those of the projected problem (normal equations on columns
    scaled to unit norm, so that the Gram matrix stays well conditioned)."""
    v = armature_columns(seg, fn_hz, zeta, arm)
    q, r = seg["fixed_q"], seg["a_perp"]
    vp = v - q @ (q.T @ v)
    norm = np.sqrt(np.einsum("ij,ij->j", vp, vp))
    norm[norm == 0.0] = 1.0
    vp /= norm
    rhs = vp.T @ r
    c, *_ = np.linalg.lstsq(vp.T @ vp, rhs, rcond=1e-12)
    return max(float(r @ r - rhs @ c), 0.0), (v @ (c / norm) if motion else None)


def residual_ms(segs: list[dict], fn_hz: float | None, zeta: float | None, arms=None) -> float:
    """Mean square residual ((m/s^2)^2) over the steps of the least-squares fit with the
    fixed columns and, unless ``fn_hz`` is None, the armature's at ``(fn_hz, zeta)``;
    ``arms``: per step, the armature's acceleration added to the riding load's plate
    acceleration (:func:`armature_columns`)."""
    sq = n = 0.0
    for i, seg in enumerate(segs):
        if fn_hz is None:
            sq += float(seg["a_perp"] @ seg["a_perp"])
        else:
            sq += _step_fit(seg, fn_hz, zeta, None if arms is None else arms[i])[0]
        n += seg["a"].size
    return sq / max(n, 1.0)


def read_armature(segs: list[dict], drive_hz: float) -> dict | None:
    """The armature's ``f_ratio`` (natural frequency over the drive's) and ``zeta`` that
    best explain the steps' accelerations (:func:`ring_segments`), and whether the
    accelerometer reads an armature at all.

    Returns None without steps, else ``{"read", "f_ratio", "zeta", "rms_m_s2",
    "rms_fixed_m_s2", "rms_ratio", "n_steps", "n_evals"}``: ``read`` when the armature's
    columns lower the residual rms by :data:`MIN_RMS_RATIO` or more (``rms_ratio``).
    """
    if not segs:
        return None
    n_evals = 0
    arms = None

    def objective(z):
        nonlocal n_evals
        r, zeta = math.exp(z[0]), math.exp(z[1])
        if not (F_RATIO_BOUNDS[0] <= r <= F_RATIO_BOUNDS[1]):
            return 1e30
        if not (ZETA_BOUNDS[0] <= zeta <= ZETA_BOUNDS[1]):
            return 1e30
        n_evals += 1
        return residual_ms(segs, r * drive_hz, zeta, arms)

    z_zeta = math.log(ZETA_START)
    coarse = [objective([math.log(r), z_zeta]) for r in F_RATIO_GRID]
    x = np.array([math.log(F_RATIO_GRID[int(np.argmin(coarse))]), z_zeta])
    ms, ms_fixed = float(min(coarse)), residual_ms(segs, None, None)
    # a grid this far from a reading is not searched further (most runs: a rigid shaker)
    passes = PASSES if math.sqrt(ms_fixed / max(ms, 1e-300)) >= GRID_STOP_RATIO else 0
    for done in range(1, passes + 1):
        res = minimize(objective, x, method="Nelder-Mead",
                       options={"xatol": XATOL, "fatol": 1e-9, "maxfev": MAX_EVALS})  # fmt: skip
        x, ms = res.x, float(res.fun)
        if done < passes:  # the next pass loads the armature with the whole plate's motion
            fn, zeta = math.exp(x[0]) * drive_hz, math.exp(x[1])
            arms = [_step_fit(seg, fn, zeta, None if arms is None else arms[i], True)[1]
                    for i, seg in enumerate(segs)]  # fmt: skip
    ratio = math.sqrt(ms_fixed / max(ms, 1e-300))
    return {
        "read": bool(ratio >= MIN_RMS_RATIO),
        "f_ratio": float(math.exp(x[0])),
        "zeta": float(math.exp(x[1])),
        "rms_m_s2": math.sqrt(ms),
        "rms_fixed_m_s2": math.sqrt(ms_fixed),
        "rms_ratio": ratio,
        "n_steps": len(segs),
        "n_evals": n_evals,
    }


def armature_from_accel(run, flights: pd.DataFrame, recording=None) -> dict | None:
    """:func:`read_armature` of a sweep run with an ``accel`` channel and its
    ``accel_v_per_g``, from the run's continuity ``flights`` (the extraction's table, or
    any with ``t_takeoff_s`` and ``t_landing_s``); None without them. ``recording``: the
    run's recording with ``accel`` already read."""
    from bouncelab.runs import read_recording, step_table

    if not accel_in_g(run):
        return None
    if not {"t_takeoff_s", "t_landing_s"} <= set(flights.columns):
        return None  # a flight table without its edge times (CONTRACTS.md section 3)
    rec = recording if recording is not None else read_recording(run, roles=("accel",))
    accel = np.asarray(rec.channels["accel"], dtype=np.float64) / float(run.accel_v_per_g)
    steps = step_table(run, rec.duration_s)
    segs = ring_segments(
        accel * G_M_S2, rec.fs, steps, flights, float(run.drive_frequency_hz), rec.time_s
    )
    return read_armature(segs, float(run.drive_frequency_hz))
