"""The drive channel's own frequency (``bouncelab.flights.phase.dominant_frequency``) and
the warning when run.yaml states another (``drive_frequency_warning``, and its use by the
diagnosis). References: the frequencies the test signals are made with."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from bouncelab.flights.phase import (
    DRIVE_FREQUENCY_TOLERANCE,
    dominant_frequency,
    drive_frequency_warning,
)
from bouncelab.gap.diagnose import drive_warnings

FS = 20_000.0


@pytest.mark.parametrize("freq_hz", [30.0, 29.37, 61.2])
def test_a_noisy_sine_with_a_harmonic_gives_its_frequency(freq_hz):
    """1.5 s of a sine (between bins for 29.37 and 61.2 Hz), 5 % noise, a 10 % second
    harmonic and an offset: within 0.005 Hz, a tenth of the warning's tolerance at 30 Hz
    (0.2 %, 0.06 Hz)."""
    t = np.arange(int(1.5 * FS)) / FS
    rng = np.random.default_rng(1)
    w = 2 * np.pi * freq_hz * t
    y = 0.2 + np.sin(w + 0.3) + 0.1 * np.sin(2 * w) + 0.05 * rng.standard_normal(t.size)
    assert dominant_frequency(y, FS) == pytest.approx(freq_hz, abs=0.005)


@pytest.mark.parametrize("cycles", [8.3, 20.5, 60.25])
def test_a_clean_sine_of_few_cycles_is_read_to_a_ten_thousandth(cycles):
    """Grandke's ratio on a Hann window (reference: the sine's own frequency), for every
    offset from a bin: within 0.01 % of the frequency over 8.3 cycles and better over
    more, where a log-parabola through three bins was 0.19 % off."""
    fs = 2000.0
    for f in 25.0 + np.linspace(0.0, 1.0, 21):
        n = int(round(cycles / f * fs))
        y = np.sin(2 * np.pi * f * np.arange(n) / fs + 0.7)
        assert dominant_frequency(y, fs) == pytest.approx(f, rel=1e-4)


def test_noise_alone_or_too_few_samples_give_nan():
    rng = np.random.default_rng(2)
    assert np.isnan(dominant_frequency(rng.standard_normal(30_000), FS))
    assert np.isnan(dominant_frequency(np.ones(10), FS))


def test_the_warning_speaks_only_beyond_the_tolerance():
    inside = 30.0 * (1.0 + 0.8 * DRIVE_FREQUENCY_TOLERANCE)
    assert drive_frequency_warning(np.array([inside, np.nan]), 30.0) is None
    assert drive_frequency_warning(np.array([np.nan, np.nan]), 30.0) is None
    text = drive_frequency_warning(np.array([25.0, 25.0, np.nan]), 30.0, "raw/x/run.yaml")
    assert text.startswith("raw/x/run.yaml: the drive channel runs at 25.000 Hz")
    assert "(median over 2 steps), -16.7 % from drive_frequency_hz 30" in text


def test_the_diagnosis_warns_from_the_qc_table_and_keeps_quiet_without_one():
    run = SimpleNamespace(drive_frequency_hz=29.0, yaml_path=Path("raw/r/run.yaml"))
    qc = pd.DataFrame({"drive_frequency_hz": [np.nan, 30.0, 30.0001]})
    (warning,) = drive_warnings(run, qc)
    assert "raw/r/run.yaml: the drive channel runs at 30.000 Hz" in warning
    assert drive_warnings(run, None) == []
    assert drive_warnings(run, qc.rename(columns={"drive_frequency_hz": "x"})) == []
    assert drive_warnings(SimpleNamespace(drive_frequency_hz=30.0, yaml_path=""), qc) == []


@pytest.mark.parametrize("true_hz", [30.0, 30.045, 30.15])
def test_phases_follow_the_drive_channel_when_run_yaml_is_off(tmp_path, true_hz):
    """The virtual rig's plate (rigid shaker: the position is A sin(2 pi f t), the drive
    channel in phase with it) at ``true_hz``, run.yaml stating 30 Hz. A sine fitted at the
    stated frequency gave each step one phase, off by pi df t towards its ends: a second
    black-box probe's 0.15 % (under validate's 0.2 % warning) had takeoff phases a median
    0.14 rad off, 0.5 % 0.47 rad. Reference: 2 pi f_true t mod 2 pi at the takeoffs;
    0.01 rad (the edge timing's 2 us is 0.0004 rad). T keeps the stated frequency
    (CONTRACTS.md section 3)."""
    import yaml

    from bouncelab.flights import extract_run
    from bouncelab.rig import run_rig

    cfg = {
        "kind": "sweep",
        "seed": 7,
        "body": {"restitution": 0.0, "friction_mu": 0.0},
        "drive": {"frequency_hz": true_hz},
        "shaker": {"feedback": False},
        "protocol": {"gammas": [0.5, 1.6, 2.2, 2.8], "cycles_per_step": 60},
    }
    (tmp_path / "rig.yaml").write_text(yaml.safe_dump(cfg))
    run_dir = tmp_path / "raw" / "off"
    run_rig(tmp_path / "rig.yaml", run_dir, tmp_path / "truth.parquet")
    spec = yaml.safe_load((run_dir / "run.yaml").read_text())
    (run_dir / "run.yaml").write_text(yaml.safe_dump(spec | {"drive_frequency_hz": 30.0}))
    flights, _ = extract_run(run_dir)
    flights = flights[np.isfinite(flights["phi_takeoff"])]
    assert len(flights) > 150  # 3 steps of 60 cycles, one flight a cycle
    expected = np.mod(2 * np.pi * true_hz * flights["t_takeoff_s"].to_numpy(), 2 * np.pi)
    error = np.angle(np.exp(1j * (flights["phi_takeoff"].to_numpy() - expected)))
    print(f"{true_hz} Hz: median |error| {np.median(np.abs(error)):.4f} rad")
    assert np.max(np.abs(error)) < 0.01
    np.testing.assert_allclose(flights["T"], 2 * np.pi * 30.0 * flights["flight_s"])


def test_phases_follow_a_drive_whose_frequency_drifts(tmp_path):
    """The virtual rig's continuity channel beside a drive channel whose frequency rises
    0.3 % over the run (30.000 to 30.090 Hz, as a black-box probe's oscillator warming
    up). Phases that followed one frequency for the run, re-anchored each step, erred up
    to 0.31 rad at the steps' ends in that probe; each step's own frequency
    (``extract.phase_frequencies``) leaves the curvature of the drift within a step:
    ``pi r D^2 / 6`` at the ends (a least-squares line through a parabola): 0.024 rad
    here (r = 0.011 Hz/s, steps of D = 2 s). Reference: the drive's own phase at the
    takeoffs; 0.03 rad. The phases are of the drive
    channel; the body's flights need not match the drifting plate for that."""
    import yaml

    from bouncelab.flights import extract_run
    from bouncelab.rig import run_rig
    from bouncelab.runs import load_run, read_recording

    cfg = {
        "kind": "sweep",
        "seed": 3,
        "body": {"restitution": 0.0, "friction_mu": 0.0},
        "drive": {"frequency_hz": 30.0},
        "shaker": {"feedback": False},
        "protocol": {"gammas": [0.5, 1.6, 2.2, 2.8], "cycles_per_step": 60},
    }
    (tmp_path / "rig.yaml").write_text(yaml.safe_dump(cfg))
    rig_dir = tmp_path / "rig_run"
    run_rig(tmp_path / "rig.yaml", rig_dir, tmp_path / "truth.parquet")
    run = load_run(rig_dir)
    rec = read_recording(run, roles=("continuity",))
    fs = float(rec.fs)
    t = np.arange(rec.n_samples) / fs
    drift, t_end = 0.003, t[-1]
    theta = 2 * np.pi * 30.0 * (t + drift * t**2 / (2 * t_end))
    run_dir = tmp_path / "raw" / "drifting"
    run_dir.mkdir(parents=True)
    np.savez(run_dir / "rec.npz", cont=rec.channels["continuity"], drive=np.sin(theta))
    spec = yaml.safe_load((rig_dir / "run.yaml").read_text())
    spec = {k: v for k, v in spec.items() if k not in ("full_scale_v",)}
    spec |= {"recording": "rec.npz", "channels": {"continuity": "cont", "drive": "drive"}}
    (run_dir / "run.yaml").write_text(yaml.safe_dump(spec))
    flights, qc = extract_run(run_dir)
    assert any("frequency changes over the run" in w for w in qc.attrs["warnings"])
    flights = flights[np.isfinite(flights["phi_takeoff"])]
    assert len(flights) > 150
    t_take = flights["t_takeoff_s"].to_numpy()
    expected = 2 * np.pi * 30.0 * (t_take + drift * t_take**2 / (2 * t_end))
    error = np.angle(np.exp(1j * (flights["phi_takeoff"].to_numpy() - expected)))
    print(f"max |error| {np.max(np.abs(error)):.4f} rad")
    assert np.max(np.abs(error)) < 0.03
    np.testing.assert_allclose(flights["T"], 2 * np.pi * 30.0 * flights["flight_s"])


def test_one_frequency_for_all_steps_unless_a_step_would_drift_off():
    """``phase_frequencies``: the common frequency while every step's own keeps its ends
    within ``PHASE_DRIFT_RAD`` of it (pi |df| D); each step's own beyond, the steps
    without one (NaN, missing) keeping the common one."""
    from bouncelab.flights.extract import PHASE_DRIFT_RAD, phase_frequencies

    steps = pd.DataFrame(
        {"step": [0, 1, 2], "t_start_s": [0.0, 2.0, 4.0], "t_end_s": [2.0, 4.0, 6.0]}
    )
    within = 0.9 * PHASE_DRIFT_RAD / (np.pi * 2.0)  # Hz off over a 2-s step
    assert phase_frequencies({0: 30.0 + within, 1: 30.0 - within}, 30.0, steps) == {
        0: 30.0,
        1: 30.0,
        2: 30.0,
    }
    beyond = 1.2 * PHASE_DRIFT_RAD / (np.pi * 2.0)
    assert phase_frequencies({0: 30.0 + beyond, 1: np.nan}, 30.0, steps) == {
        0: 30.0 + beyond,
        1: 30.0,
        2: 30.0,
    }


def test_a_step_with_samples_missing_is_read_on_its_longest_even_stretch():
    """Samples missing from a ``time_s`` axis (a DAQ's overrun) made the step's spectrum
    that of a sine with a phase jump: a probe's steps read up to 0.8 rad of drift that
    was not there. Reference: the sine's frequency, 1e-4."""
    from bouncelab.flights.extract import drive_frequencies

    fs, f = 2000.0, 30.0
    t = np.arange(int(4.0 * fs)) / fs
    keep = np.ones(t.size, dtype=bool)
    keep[3000:3137] = False  # 68.5 ms missing: a phase jump of 2 pi f 0.0685
    t = t[keep]
    y = np.sin(2 * np.pi * f * t)
    steps = pd.DataFrame({"step": [0], "gamma": [2.0], "t_start_s": [0.0], "t_end_s": [4.0]})
    assert drive_frequencies(y, steps, fs, f, t)[0] == pytest.approx(f, rel=1e-4)
