"""The shaker's armature read from a plate accelerometer (flights.armature).

References: a synthetic accelerometer signal made from the reader's own model (a damped
oscillator kicked at irregular landings, beside the drive and white noise), whose
``f_a`` and ``zeta`` are known exactly; and the shipped ``raw/accel_g2-4``, made by the
virtual rig with the armature of ``config/rig/accel_g2-4.yaml`` (18 Hz at a 35 Hz drive,
zeta 0.04). Tolerances: f_ratio 1 %, zeta 15 % (``benchmarks/bench_accel_armature.py``
measures at most 0.5 % and 11 % over the rig's armatures read).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from bouncelab.flights import extract_run
from bouncelab.flights.armature import (
    MIN_RMS_RATIO,
    armature_from_accel,
    read_armature,
    ring_segments,
)
from bouncelab.runs import load_run

REPO = Path(__file__).resolve().parents[2]
FS = 20000.0
DRIVE_HZ = 30.0


def synthetic(f_a_hz: float | None, zeta: float, seed: int = 0, n_steps: int = 4):
    """Plate acceleration (m/s^2) of ``n_steps`` steps of 1.5 s at Gamma 2.5: the drive,
    0.5 g of white noise and, unless ``f_a_hz`` is None, an armature kicked by 0.01-0.03
    m/s at one landing a cycle, each at a random phase (so the rings do not repeat with
    the drive). Returns the signal, the steps and the flights (1 ms contacts)."""
    rng = np.random.default_rng(seed)
    step_s = 1.5
    t = np.arange(int(n_steps * step_s * FS)) / FS
    a = 2.5 * 9.80665 * np.sin(2 * math.pi * DRIVE_HZ * t)
    n_cycles = int(n_steps * step_s * DRIVE_HZ)
    land = (np.arange(n_cycles) + rng.uniform(0.1, 0.9, n_cycles)) / DRIVE_HZ
    if f_a_hz is not None:
        wn = 2 * math.pi * f_a_hz
        al, wd = zeta * wn, wn * math.sqrt(1 - zeta * zeta)
        for t0, dv in zip(land, rng.uniform(0.01, 0.03, n_cycles), strict=True):
            i = int(math.ceil(t0 * FS))
            tau = t[i:] - t0
            e, s, c = np.exp(-al * tau), np.sin(wd * tau), np.cos(wd * tau)
            a[i:] += dv * (-wn * wn * e * s / wd - 2 * al * e * (c - al / wd * s))
    a += 0.5 * 9.80665 * rng.standard_normal(t.size)
    steps = pd.DataFrame(
        {
            "step": np.arange(n_steps),
            "gamma": np.full(n_steps, 2.5),
            "t_start_s": np.arange(n_steps) * step_s,
            "t_end_s": (np.arange(n_steps) + 1) * step_s,
        }
    )
    flights = pd.DataFrame({"t_takeoff_s": land[:-1] + 1e-3, "t_landing_s": land[1:]})
    return a, steps, flights


@pytest.mark.parametrize(("f_a_hz", "zeta"), [(18.0, 0.04), (45.0, 0.1)])
def test_reads_a_known_ring(f_a_hz, zeta):
    a, steps, flights = synthetic(f_a_hz, zeta)
    out = read_armature(ring_segments(a, FS, steps, flights, DRIVE_HZ), DRIVE_HZ)
    assert out["read"] and out["rms_ratio"] >= MIN_RMS_RATIO
    assert out["n_steps"] == 4
    assert out["f_ratio"] == pytest.approx(f_a_hz / DRIVE_HZ, rel=0.01)
    assert out["zeta"] == pytest.approx(zeta, rel=0.15)


def test_no_ring_reads_no_armature():
    a, steps, flights = synthetic(None, 0.0)
    out = read_armature(ring_segments(a, FS, steps, flights, DRIVE_HZ), DRIVE_HZ)
    assert not out["read"] and out["rms_ratio"] < MIN_RMS_RATIO


def test_chatter_steps_and_low_gamma_are_left_out():
    a, steps, flights = synthetic(18.0, 0.04)
    steps.loc[0, "gamma"] = 0.9  # the body rests: nothing to read
    dense = np.sort(np.concatenate([flights["t_landing_s"], np.arange(1.5, 3.0, 1 / 150)]))
    many = pd.DataFrame({"t_takeoff_s": dense - 1e-3, "t_landing_s": dense})  # 5 a cycle
    assert len(ring_segments(a, FS, steps, many, DRIVE_HZ)) == 2  # steps 2 and 3
    assert read_armature([], DRIVE_HZ) is None


def test_the_shipped_accelerometer_run_reads_its_armature():
    run_dir = REPO / "raw" / "accel_g2-4"
    flights, _qc = extract_run(run_dir)
    out = armature_from_accel(load_run(run_dir), flights)
    assert out["read"]
    assert out["f_ratio"] == pytest.approx(18.0 / 35.0, rel=0.01)
    assert out["zeta"] == pytest.approx(0.04, rel=0.15)


def test_no_accel_channel_or_no_edge_times_reads_nothing():
    assert armature_from_accel(load_run(REPO / "raw" / "sweep_g0-4"), pd.DataFrame()) is None
    no_edges = pd.DataFrame({"step": [0], "T": [1.0]})
    assert armature_from_accel(load_run(REPO / "raw" / "accel_g2-4"), no_edges) is None
