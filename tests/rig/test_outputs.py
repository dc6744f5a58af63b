"""Run folders: every format read back by bouncelab.runs, determinism, truth, sensors."""

from __future__ import annotations

import hashlib
import math

import numpy as np
import pytest
from rig_helpers import quiet_config

from bouncelab.rig import read_truth, run_rig, write_run, write_truth
from bouncelab.rig.sensors import adc_codes, codes_to_volts

FORMATS = ["flac", "wav", "csv", "npz", "tdms"]


@pytest.fixture(scope="module")
def small(simulate):
    """1 s sweep at Gamma 1.5 and 3 with all three channels and noise on."""
    from bouncelab.rig import parse_rig_config

    cfg = parse_rig_config(
        {
            "kind": "sweep",
            "seed": 7,
            "protocol": {"gammas": [1.5, 3.0], "cycles_per_step": 15},
            "sensors": {"accel": {"enabled": True}},
        }
    )
    return simulate(cfg)


@pytest.mark.parametrize("fmt", FORMATS)
def test_round_trip_through_the_run_reader(small, tmp_path, fmt):
    """What bouncelab.runs reads back equals the ADC volts: exactly for audio (codes x
    full_scale_v / 32768), NPZ and TDMS (float64), to 1e-9 V for CSV (10 digits)."""
    from bouncelab.runs import load_run, read_recording, validate_run

    run_dir = write_run(small, tmp_path / f"run_{fmt}", fmt, csv_time_column=(fmt == "csv"))
    run = load_run(run_dir)
    assert run.source == "synthetic" and run.kind == "sweep"
    rec = read_recording(run)
    assert rec.fs == 20000 and rec.n_samples == small.n_samples
    volts = codes_to_volts(small.codes, small.full_scale_v)
    tol = 1e-9 if fmt == "csv" else 0.0
    for j, role in enumerate(small.roles):
        np.testing.assert_allclose(rec.channels[role], volts[:, j], rtol=0, atol=tol)
    validate_run(run_dir)  # raises on any problem


def test_same_config_same_bytes(small, simulate, tmp_path):
    """Determinism: a second simulation of the same config writes identical files in
    every format, and an identical truth Parquet (no timestamps anywhere)."""
    again = simulate(small.params["config"])
    for fmt in FORMATS:
        a = write_run(small, tmp_path / "a" / fmt, fmt)
        b = write_run(again, tmp_path / "b" / fmt, fmt)
        for name in ("run.yaml", f"recording.{fmt}"):
            ha = hashlib.sha256((a / name).read_bytes()).hexdigest()
            assert ha == hashlib.sha256((b / name).read_bytes()).hexdigest(), (fmt, name)
    ta = write_truth(small.truth, small.params, tmp_path / "ta.parquet")
    tb = write_truth(again.truth, again.params, tmp_path / "tb.parquet")
    assert ta.read_bytes() == tb.read_bytes()


def test_other_seed_other_noise(small, simulate):
    """The seed drives the noise: another seed changes the samples, not the physics."""
    cfg = dict(small.params["config"], seed=8)
    other = simulate(cfg)
    assert not np.array_equal(other.codes, small.codes)
    np.testing.assert_array_equal(other.truth["t_takeoff_s"], small.truth["t_takeoff_s"])


def test_truth_round_trip(small, tmp_path):
    """read_truth gives back the flights and every parameter (config and derived)."""
    path = write_truth(small.truth, small.params, tmp_path / "t.parquet")
    flights, params = read_truth(path)
    np.testing.assert_array_equal(flights["t_landing_s"], small.truth["t_landing_s"])
    assert params["config"] == small.params["config"]
    assert params["derived"]["contact_zeta"] == pytest.approx(0.20667, abs=1e-5)
    assert set(flights.columns) >= {"t_takeoff_s", "t_landing_s", "flight_s", "step", "gamma"}


def test_truth_flights_are_what_the_circuit_sees(simulate):
    """Without noise, the continuity signal crosses mid-level within one sample of every
    true edge, after the RC front end's delay tau ln 2 (6.9 us for tau = 10 us): the
    truth's flights are the circuit's open intervals. Checked on flights longer than
    2 ms after a contact longer than 0.5 ms (shorter ones are smeared by the RC and the
    50 us sampling)."""
    res = simulate(
        quiet_config(body={"restitution": 0.0}, protocol={"gammas": [2.0], "cycles_per_step": 20})
    )
    v = codes_to_volts(res.codes[:, 0], res.full_scale_v)
    fs = res.fs
    up = np.flatnonzero((v[:-1] < 2.5) & (v[1:] >= 2.5))  # contact (0 V) -> open (5 V)
    t_up = (up + (2.5 - v[up]) / (v[up + 1] - v[up])) / fs
    tr = res.truth
    contact_before = tr["t_takeoff_s"] - tr["t_landing_s"].shift(1)
    long = tr[(tr["flight_s"] > 2e-3) & (contact_before > 5e-4)]
    assert len(long) >= 10
    delay = 1e-5 * math.log(2)
    for t in long["t_takeoff_s"]:
        assert np.min(np.abs(t_up - (t + delay))) < 1.0 / fs


def test_drive_channel_phase_convention(simulate):
    """Drive reference: zero phase at the upward zero crossing of the commanded plate
    position, i.e. at t = k / f; amplitude v_per_gamma x Gamma (0.5 V x 2 = 1 V).
    Fit a sin + b cos at the drive frequency: phase 0 within 1e-3 rad, amplitude 1e-3 V."""
    res = simulate(quiet_config(protocol={"gammas": [2.0], "cycles_per_step": 20}))
    drive = codes_to_volts(res.codes[:, 1], res.full_scale_v)
    t = np.arange(drive.size) / res.fs
    sl = t > 2 / 30  # after the amplitude ramp
    w = 2 * math.pi * 30.0
    basis = np.column_stack([np.sin(w * t[sl]), np.cos(w * t[sl])])
    (a, b), *_ = np.linalg.lstsq(basis, drive[sl], rcond=None)
    assert math.atan2(b, a) == pytest.approx(0.0, abs=1e-3)
    assert math.hypot(a, b) == pytest.approx(1.0, abs=1e-3)


def test_adc_is_16_bit():
    """Quantisation step full_scale / 32768; clipping at the rails."""
    codes = adc_codes(np.array([0.0, 10.0 / 32768 * 0.6, 20.0, -20.0]), 10.0)
    assert codes.tolist() == [0, 1, 32767, -32768]


def test_sensor_delay_shifts_the_continuity_channel(simulate):
    """effects.sensor_delay_s = 1 ms moves every circuit edge 1 ms (20 samples) later;
    the truth (physical flights) is unchanged."""
    base = quiet_config(protocol={"gammas": [2.0], "cycles_per_step": 12})
    late = dict(base, effects=dict(base["effects"], sensor_delay_s=1e-3))
    a, b = simulate(base), simulate(late)
    np.testing.assert_array_equal(a.truth["t_takeoff_s"], b.truth["t_takeoff_s"])
    np.testing.assert_array_equal(a.codes[1000:-100, 0], b.codes[1020:-80, 0])


def test_run_rig_writes_run_and_truth(tmp_path):
    """run_rig: config file in, run folder and truth file out (CLI path)."""
    cfg = tmp_path / "c.yaml"
    cfg.write_text("kind: drop\nprotocol: {release_t_s: 0.05, duration_s: 0.3}\n")
    res = run_rig(cfg, tmp_path / "drop1", tmp_path / "truth.parquet")
    flights, params = read_truth(tmp_path / "truth.parquet")
    assert len(flights) == len(res.truth) > 3
    assert params["config"]["kind"] == "drop"
    assert sorted(p.name for p in (tmp_path / "drop1").iterdir()) == [
        "recording.flac",
        "run.yaml",
    ]
