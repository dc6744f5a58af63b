"""Experiment: how well a plate accelerometer measures the shaker's armature.

Not part of the package and not used by ``bouncelab diagnose``: a measurement of
whether the information the flight times lack (docs/diagnosis.md, section 5: the
armature's damping ratio of the seed-like cases is 25-180 % off) is in an ``accel``
channel, and at what cost. The virtual rig makes a run from ``--rig-config`` (with
``sensors.accel.enabled``), the continuity flights are extracted as usual, and the
armature is identified from the accelerometer alone; the errors against the rig's
ground truth and the time are printed and written to
``benchmarks/results/accel_armature_<config name>.json``.

Method, per Gamma step with Gamma > 1: the accelerometer (m/s^2, ``accel_v_per_g``) is
low-passed at ``LOWPASS_DRIVES`` drive frequencies (zero phase), decimated, and fitted by
least squares with

- the drive (constant, 5 harmonics) and 50 Hz hum;
- the armature's free response from the step's start (2 columns);
- per continuity landing: the armature's acceleration after a velocity kick (free
  amplitude) and the low-passed impact spike (free amplitude: the rig samples the
  acceleration at an instant, so a 40 us impact spike is caught or missed by luck, as
  an accelerometer without an anti-alias filter would; tying it to the kick biased
  everything);
- the riding body's load ``-(g + a_plate)`` during contacts through the oscillator
  (coefficient: the mass ratio), and ``g sign(v_plate)`` for the pole's friction.

The armature is ``M y'' + c y' + k y = -F`` (plate = command + y), so the kernels are a
damped oscillator's; the mean square residual is profiled over ``f_n`` (coarse grid)
and then over ``(f_n, zeta)`` by Nelder-Mead, twice (the second time with the fitted
armature motion in the load's ``a_plate``: a riding body adds its mass).

Run: ``python benchmarks/bench_accel_armature.py --rig-config CONFIG``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.optimize import minimize
from scipy.signal import bilinear, butter, lfilter, sosfiltfilt

from bouncelab.flights import extract_run
from bouncelab.flights.accel import drive_basis
from bouncelab.rig import read_truth, run_rig
from bouncelab.runs import load_run, read_recording, step_table

ROOT = Path(__file__).resolve().parents[1]
G_M_S2 = 9.80665
LOWPASS_DRIVES = 6.0  # low-pass corner in drive frequencies
SAMPLES_PER_CORNER = 3.0  # decimated samples per corner period
N_HARMONICS = 5
HUM_HZ = 50.0
F_RATIO_GRID = np.exp(np.linspace(math.log(0.2), math.log(3.0), 17))
ZETA_START = 0.05


def segments(accel, fs, steps, flights, drive_hz):
    """Per Gamma step (> 1, two landings or more): decimated time from the step's start
    (s), low-passed acceleration (m/s^2), landings (s from the step's start), contact
    mask; and the low-pass's response to a unit-area spike (1/s) with its lag grid (s)."""
    fc = min(LOWPASS_DRIVES * drive_hz, 0.2 * fs)
    sos = butter(4, fc, fs=fs, output="sos")
    af = sosfiltfilt(sos, np.asarray(accel, dtype=np.float64))
    q = max(1, int(fs // (SAMPLES_PER_CORNER * fc)))
    t_all = np.arange(af.size) / fs
    half = int(math.ceil(4.0 / fc * fs))
    unit = np.zeros(2 * half + 1)
    unit[half] = fs
    spike = sosfiltfilt(sos, unit)
    lag = (np.arange(spike.size) - half) / fs
    land_all = np.sort(flights["t_landing_s"].to_numpy(dtype=np.float64))
    take_all = np.sort(flights["t_takeoff_s"].to_numpy(dtype=np.float64))
    out = []
    for st in steps.itertuples(index=False):
        if st.gamma <= 1.0:
            continue
        i0, i1 = np.searchsorted(t_all, [st.t_start_s, st.t_end_s])
        idx = np.arange(i0, i1, q)
        land = land_all[(land_all >= st.t_start_s) & (land_all < st.t_end_s)]
        if idx.size < 64 or land.size < 2:
            continue
        nxt = np.minimum(np.searchsorted(take_all, land), take_all.size - 1)
        take = np.where(take_all[nxt] > land, take_all[nxt], st.t_end_s)
        t = t_all[idx]
        edges = np.zeros(t.size + 1, dtype=np.int64)
        np.add.at(edges, np.searchsorted(t, land), 1)
        np.add.at(edges, np.searchsorted(t, take), -1)
        out.append((t - t[0], af[idx], land - t[0], np.cumsum(edges)[: t.size] > 0))
    return out, spike, lag


def drive_columns(t, drive_hz):
    return drive_basis(t, drive_hz, N_HARMONICS, (HUM_HZ,))


def design(seg, drive_hz, fn_hz, zeta, spike, lag, a_arm=None):
    """Design matrix of one step and the index of the load column."""
    t, a, land, contact = seg
    drive = drive_columns(t, drive_hz)
    wn = 2.0 * math.pi * fn_hz
    al = zeta * wn
    wd = wn * math.sqrt(max(1.0 - zeta * zeta, 1e-12))
    free = np.stack([np.exp(-al * t) * np.cos(wd * t), np.exp(-al * t) * np.sin(wd * t)], axis=1)
    tau = t[:, None] - land[None, :]
    tp = np.maximum(tau, 0.0)
    e = np.exp(-al * tp)
    s, c = np.sin(wd * tp), np.cos(wd * tp)
    kicks = np.where(tau >= 0.0, -wn * wn * e * s / wd - 2.0 * al * e * (c - al / wd * s), 0.0)
    spikes = np.interp(tau, lag, spike, left=0.0, right=0.0)
    coef, *_ = np.linalg.lstsq(drive, a, rcond=None)
    a_plate = drive[:, 1:] @ coef[1:] + (0.0 if a_arm is None else a_arm)
    w = 2.0 * math.pi * drive_hz
    v_plate = sum(
        (-coef[2 * h - 1] * np.cos(h * w * t) + coef[2 * h] * np.sin(h * w * t)) / (h * w)
        for h in range(1, N_HARMONICS + 1)
    )
    b, aa = bilinear([-1.0, 0.0, 0.0], [1.0, 2.0 * al, wn * wn], 1.0 / (t[1] - t[0]))
    load = lfilter(b, aa, np.where(contact, G_M_S2 + a_plate, 0.0))
    pole = lfilter(b, aa, np.where(contact, G_M_S2 * np.sign(v_plate), 0.0))
    X = np.concatenate([drive, free, kicks, spikes, load[:, None], pole[:, None]], axis=1)
    return X, X.shape[1] - 2, drive.shape[1]


def fit_all(segs, drive_hz, fn_hz, zeta, spike, lag, arms=None):
    """Mean square residual ((m/s^2)^2), the load coefficient (weighted over steps), and
    each step's fitted armature acceleration."""
    sq = n = 0.0
    num = den = 0.0
    fitted = []
    for i, seg in enumerate(segs):
        X, j, nd = design(seg, drive_hz, fn_hz, zeta, spike, lag, None if arms is None else arms[i])
        coef, *_ = np.linalg.lstsq(X, seg[1], rcond=None)
        r = seg[1] - X @ coef
        sq += float(r @ r)
        n += r.size
        wj = float(X[:, j] @ X[:, j])
        num += coef[j] * wj
        den += wj
        fitted.append(X[:, nd:] @ coef[nd:])
    return sq / max(n, 1.0), num / max(den, 1e-300), fitted


def rigid_ms(segs, drive_hz):
    sq = n = 0.0
    for t, a, _land, _c in segs:
        X = drive_columns(t, drive_hz)
        coef, *_ = np.linalg.lstsq(X, a, rcond=None)
        r = a - X @ coef
        sq += float(r @ r)
        n += r.size
    return sq / max(n, 1.0)


def identify(segs, drive_hz, spike, lag):
    """f_ratio, zeta, mass_ratio and the residual rms (m/s^2); evaluations counted."""
    coarse = [
        fit_all(segs, drive_hz, r * drive_hz, ZETA_START, spike, lag)[0] for r in F_RATIO_GRID
    ]
    x = np.array([math.log(F_RATIO_GRID[int(np.argmin(coarse))]), math.log(ZETA_START)])
    arms, n_evals = None, len(coarse)
    for _ in range(2):

        def objective(z, arms=arms):
            r, zeta = math.exp(z[0]), math.exp(z[1])
            if not (0.05 <= r <= 5.0 and 0.002 <= zeta <= 0.9):
                return 1e30
            return fit_all(segs, drive_hz, r * drive_hz, zeta, spike, lag, arms)[0]

        res = minimize(objective, x, method="Nelder-Mead",
                       options={"xatol": 3e-3, "fatol": 1e-9, "maxfev": 50})  # fmt: skip
        x, n_evals = res.x, n_evals + res.nfev
        ms, ratio, arms = fit_all(segs, drive_hz, math.exp(x[0]) * drive_hz, math.exp(x[1]),
                                  spike, lag, arms)  # fmt: skip
    return {
        "f_ratio": math.exp(x[0]),
        "zeta": math.exp(x[1]),
        "mass_ratio": float(ratio),
        "rms_m_s2": math.sqrt(ms),
        "rigid_rms_m_s2": math.sqrt(rigid_ms(segs, drive_hz)),
        "n_evals": n_evals,
    }


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--rig-config", required=True, help="rig config with sensors.accel enabled")
    args = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        run_dir = Path(tmp) / Path(args.rig_config).stem
        run_rig(args.rig_config, run_dir, Path(tmp) / "truth.parquet")
        run = load_run(run_dir)
        if "accel" not in run.channels:
            raise SystemExit(f"{args.rig_config}: the run has no accel channel")
        rec = read_recording(run, roles=("accel",))
        flights, _qc = extract_run(run_dir)
        f = float(run.drive_frequency_hz)
        t0 = time.perf_counter()
        accel = rec.channels["accel"].astype(np.float64) / float(run.accel_v_per_g) * G_M_S2
        segs, spike, lag = segments(accel, rec.fs, step_table(run, rec.duration_s), flights, f)
        est = identify(segs, f, spike, lag)
        total_s = time.perf_counter() - t0
        _f, truth = read_truth(Path(tmp) / "truth.parquet")
    shaker, derived = truth["config"]["shaker"], truth["derived"]
    true = {
        "f_ratio": derived["f_ratio"],
        "zeta": shaker["damping_ratio"],
        "mass_ratio": derived["mass_ratio"],
    }
    out = {
        "config": str(Path(args.rig_config).name),
        "feedback": bool(shaker["feedback"]),
        "n_steps": len(segs),
        "estimate": est,
        "truth": true if shaker["feedback"] else None,
        "rel_errors": {k: abs(est[k] - v) / v for k, v in true.items()}
        if shaker["feedback"]
        else None,
        "identify_s": round(total_s, 2),
        "cpu_count": os.cpu_count(),
        "python": platform.python_version(),
        "machine": platform.machine(),
    }
    print(json.dumps(out, indent=1))
    path = ROOT / "benchmarks" / "results" / f"accel_armature_{Path(args.rig_config).stem}.json"
    path.write_text(json.dumps(out, indent=1, sort_keys=True) + "\n")


if __name__ == "__main__":
    main()
