"""Extraction against the virtual rig's ground truth (bouncelab.rig, read_truth).

Issue 4 targets, for e = 0 and e = 0.515, at the shipped continuity noise (rig default
0.002 V) and at three times it: median flight-duration error < 10 us, 99th percentile
< 50 us; >= 99.5 % of true flights longer than 1 ms found; <= 0.1 % false flights.
A true flight is found when a detected flight has both edges within 0.3 ms of it; a
detected flight is false when no true flight is within 0.3 ms at both edges.
True flights whose landing lies after the last sample are not observable and skipped.
The duration errors are taken over the found true flights longer than 1 ms (the same
population as the "found" criterion); sub-millisecond chatter flights are printed
apart (``all_median_us``, ``all_p99_us``): some of their openings are shorter than what
one sample can show, and a missed one makes its neighbour match the wrong flight.
"""

import shutil

import numpy as np
import pandas as pd
import pytest
import yaml

from bouncelab.flights import extract_run
from bouncelab.flights.extract import DRIVE_CHANNEL_LINE
from bouncelab.flights.extract import pressed_takeoffs as extract_pressed
from bouncelab.gap.diagnose import extraction_warnings
from bouncelab.rig import read_truth
from bouncelab.tables import read_table, write_table

GAMMAS = [0.5, 1.2, 1.6, 2.2, 2.8, 3.4, 4.2]
TOL_S = 0.3e-3


def rig_sweep(e, noise_v, seed):
    return {
        "kind": "sweep",
        "seed": seed,
        "body": {"restitution": e},
        "protocol": {"gammas": GAMMAS, "cycles_per_step": 60},
        "sensors": {"continuity": {"noise_v": noise_v}},
    }


def nearest(ref, x):
    j = np.clip(np.searchsorted(ref, x), 1, len(ref) - 1)
    return np.where(np.abs(ref[j - 1] - x) < np.abs(ref[j] - x), j - 1, j)


def accuracy(flights, truth, duration_s):
    tr = truth[truth["t_landing_s"] < duration_s - 1 / 20_000]
    tt, tl = tr["t_takeoff_s"].to_numpy(), tr["t_landing_s"].to_numpy()
    mt, ml = flights["t_takeoff_s"].to_numpy(), flights["t_landing_s"].to_numpy()
    j = nearest(mt, tt)
    found = (np.abs(mt[j] - tt) < TOL_S) & (np.abs(ml[j] - tl) < TOL_S)
    long = tr["flight_s"].to_numpy() > 1e-3
    err_all = np.abs((ml[j] - mt[j]) - (tl - tt))[found]
    err = np.abs((ml[j] - mt[j]) - (tl - tt))[found & long]
    i = nearest(tt, mt)
    real = (np.abs(tt[i] - mt) < TOL_S) & (np.abs(tl[i] - ml) < TOL_S)
    return {
        "n_true": len(tt),
        "n_detected": len(mt),
        "found_long": float(found[long].mean()),
        "false": float(1.0 - real.mean()),
        "median_us": float(np.median(err) * 1e6),
        "p99_us": float(np.percentile(err, 99) * 1e6),
        "all_median_us": float(np.median(err_all) * 1e6),
        "all_p99_us": float(np.percentile(err_all, 99) * 1e6),
    }


@pytest.mark.parametrize("e", [0.0, 0.515])
@pytest.mark.parametrize("noise_factor", [1, 3])
def test_accuracy_against_rig_truth(make_rig, e, noise_factor):
    run_dir, truth_path = make_rig(
        f"acc_e{e}_n{noise_factor}", rig_sweep(e, 0.002 * noise_factor, seed=11 + noise_factor)
    )
    flights, qc = extract_run(run_dir)
    truth, params = read_truth(truth_path)
    acc = accuracy(flights, truth, params["derived"]["duration_s"])
    print(f"e={e} noise x{noise_factor}: {acc}")
    # issue 4 goals: median < 10 us, p99 < 50 us, over found flights > 1 ms and over all
    assert acc["median_us"] < 10.0
    assert acc["p99_us"] < 50.0
    assert acc["all_median_us"] < 10.0
    assert acc["all_p99_us"] < 50.0
    assert acc["found_long"] >= 0.995
    assert acc["false"] <= 0.001
    # Gamma < 1: the body rests, no flights (reference: takeoff needs Gamma sin(phi) > 1+mu)
    assert qc.loc[qc["gamma"] < 1, "flights"].eq(0).all()
    assert (flights["gamma"] >= 1).all()


def test_a_front_end_slower_than_the_sampling(make_rig):
    """The rig's inelastic body through a 100 us RC front end (2 samples at 20 kHz: a
    pull-up with a filter capacitor). No edge then settles within 0.1 of its level two
    samples on, so q came out 0, the box model read every RC tail as edges and the table
    held 1734 "flights" for 358 true, none of them right. Read from the decays that hold
    one ratio, q is right and the rig's truth is met as at 10 us (issue 4 goals: every
    flight over 1 ms found, none invented, median < 10 us, p99 < 50 us)."""
    cfg = rig_sweep(0.0, 0.002, seed=3)
    cfg["sensors"]["continuity"]["rc_time_s"] = 100e-6
    run_dir, truth_path = make_rig("slow_rc", cfg)
    flights, _ = extract_run(run_dir)
    truth, params = read_truth(truth_path)
    acc = accuracy(flights, truth, params["derived"]["duration_s"])
    print(f"100 us RC: {acc}")
    assert acc["found_long"] == 1.0 and acc["false"] == 0.0
    assert acc["median_us"] < 10.0 and acc["p99_us"] < 50.0


def test_phase_and_settled(make_rig):
    """From rest on the plate with Coulomb friction the body leaves where
    Gamma sin(phi) = 1 + mu (DESIGN.md section 1).  With the rig's mu = 0.29, e = 0 and
    a still armature (feedback off, so the plate follows the drive reference exactly)
    every settled flight at Gamma 1.6 and 2.0 starts from sticking: phi_takeoff =
    arcsin(1.29 / Gamma) to 0.01 rad (the friction regularisation delays it ~25 us)."""
    cfg = rig_sweep(0.0, 0.002, seed=3)
    cfg["shaker"] = {"feedback": False}
    cfg["protocol"] = {"gammas": [0.5, 1.6, 2.0], "cycles_per_step": 40}
    run_dir, _ = make_rig("phase", cfg)
    flights, qc = extract_run(run_dir)
    # the drive reference's own frequency, measured per step: the rig's 30 Hz
    assert np.allclose(qc["drive_frequency_hz"], 30.0, atol=0.01), qc["drive_frequency_hz"]
    for gamma in (1.6, 2.0):
        f = flights[(flights["gamma"] == gamma) & flights["settled"]]
        want = np.arcsin(1.29 / gamma)
        got = np.median(f["phi_takeoff"])
        print(f"Gamma {gamma}: phi_takeoff median {got:.4f} rad, expected {want:.4f}")
        assert got == pytest.approx(want, abs=0.01)
    # settled: false exactly for flights within settle_cycles (10) of the step start
    # (steps of 40 cycles at 30 Hz start every 4/3 s)
    t_step = flights["step"] * 40 / 30.0
    early = flights["t_takeoff_s"] - t_step < 10 / 30.0
    assert (flights["settled"] == ~early).all()
    assert np.allclose(flights["T"], 2 * np.pi * 30.0 * flights["flight_s"])
    assert ((flights["phi_takeoff"] >= 0) & (flights["phi_takeoff"] < 2 * np.pi)).all()


@pytest.mark.parametrize("contact_v, open_v", [(0.0, 5.0), (5.0, 0.0)])
def test_auto_polarity_where_contacts_outlast_flights(make_rig, tmp_path, contact_v, open_v):
    """A sweep with no step below Gamma 1 (so no rest to read the contact level from) and
    only Gammas where the body is on the plate most of each cycle: the share-of-time rule
    alone took the contacts for flights (a black-box probe's Gamma 1.2-1.3 run: all 900
    'flights' were contacts, median takeoff phase 3.4 rad, and no word of it). The drive's
    phases of the takeoffs from rest, at asin(1 / Gamma), set it right. Reference: the
    rig's truth; targets as above (found >= 99.5 %, false <= 0.1 %)."""
    cfg = {
        "kind": "sweep",
        "seed": 5,
        "body": {"restitution": 0.0},
        "protocol": {"gammas": [1.15, 1.25, 1.35], "cycles_per_step": 120},
        "sensors": {"continuity": {"contact_v": contact_v, "open_v": open_v}},
    }
    rig_dir, truth_path = make_rig(f"low_gamma_only_{contact_v:g}", cfg)
    run_dir = tmp_path / "auto"
    shutil.copytree(rig_dir, run_dir)
    spec = yaml.safe_load((run_dir / "run.yaml").read_text())
    (run_dir / "run.yaml").write_text(yaml.safe_dump(spec | {"contact_level": "auto"}))
    flights, _ = extract_run(run_dir)
    truth, params = read_truth(truth_path)
    acc = accuracy(flights, truth, params["derived"]["duration_s"])
    print(acc)
    assert acc["found_long"] >= 0.995 and acc["false"] <= 0.001
    contact = flights["contact_before_s"].to_numpy()[1:]
    assert np.median(contact) > np.median(flights["flight_s"])  # contacts do outlast flights


def test_auto_polarity_unchecked_without_a_drive_is_a_warning(make_rig, tmp_path, caplog):
    """The same low-Gamma sweep with no drive channel: nothing can check the share-of-time
    rule there, and it reads the levels the wrong way round; extract says so and how to
    mend it (set contact_level)."""
    cfg = {
        "kind": "sweep",
        "seed": 5,
        "body": {"restitution": 0.0},
        "protocol": {"gammas": [1.15, 1.25, 1.35], "cycles_per_step": 120},
        "sensors": {"drive": {"enabled": False}},
    }
    rig_dir, _ = make_rig("low_gamma_only_no_drive", cfg)
    run_dir = tmp_path / "auto"
    shutil.copytree(rig_dir, run_dir)
    spec = yaml.safe_load((run_dir / "run.yaml").read_text())
    (run_dir / "run.yaml").write_text(yaml.safe_dump(spec | {"contact_level": "auto"}))
    with caplog.at_level("WARNING"):
        _, qc = extract_run(run_dir)
    assert "set contact_level in run.yaml" in caplog.text
    # kept with the QC table, through its Parquet file, for the diagnosis to carry
    (line,) = qc.attrs["warnings"]
    assert line.startswith(str(run_dir)) and "set contact_level in run.yaml" in line
    kept = read_table(write_table(qc, tmp_path / "flights.qc.parquet"))
    assert kept.attrs["warnings"] == [line]
    assert extraction_warnings(kept) == [line] and extraction_warnings(None) == []
    caplog.clear()
    with caplog.at_level("WARNING"):
        _, qc = extract_run(rig_dir)  # contact_level stated: no doubt, no warning
    assert "contact_level" not in caplog.text and qc.attrs["warnings"] == []


def test_the_drive_channel_line_is_said_once_where_the_diagnosis_warns_of_it():
    qc = pd.DataFrame({"step": [0]})
    qc.attrs["warnings"] = [
        f"rec.wav: {DRIVE_CHANNEL_LINE} 30.3000 Hz, +1.00 % from drive_frequency_hz 30: ...",
        "rec.wav: 3 takeoff(s) from rest while the plate pushed the body up ...",
    ]
    assert extraction_warnings(qc) == qc.attrs["warnings"]
    assert extraction_warnings(qc, drive_warned=True) == qc.attrs["warnings"][1:]


@pytest.mark.parametrize("dropouts", [0, 12])
def test_openings_of_a_resting_contact_are_warned_about(make_rig, tmp_path, caplog, dropouts):
    """A dirty contact opens the circuit for 2-3 samples while the rig's inelastic body
    rests (Gamma 0.5) or rides (Gamma 1.2-1.6): each opening reads as a flight, which a
    black-box probe met 105 times, 39 at Gamma 1.0, with no word. Kept in the table, but
    those that leave a rest while the plate pushes the body up (sin phi < -0.5: about
    half of openings at random phases) are counted and warned about; the same recording
    without openings gives no warning, nor do the shipped runs."""
    from flights_synth import write_npz_run

    from bouncelab.runs import load_run, read_recording

    cfg = rig_sweep(0.0, 0.002, seed=3)
    cfg["protocol"] = {"gammas": [0.5, 1.2, 1.6], "cycles_per_step": 60}
    run_dir, _ = make_rig("rest_rides", cfg)
    run, rec = load_run(run_dir), read_recording(run_dir)
    x = rec.channels["continuity"].copy()
    lo, hi = np.percentile(x, [1, 99])
    rng = np.random.default_rng(7)
    # openings inside contacts of at least 3 ms (x near the contact level, the lower)
    contact = np.flatnonzero(np.convolve(x < 0.5 * (lo + hi), np.ones(60), "same") >= 60)
    for k in rng.choice(contact, size=dropouts, replace=False):
        x[k : k + 2 + k % 2] = hi
    spec = {
        "kind": "sweep", "drive_frequency_hz": run.drive_frequency_hz,
        "contact_level": "low", "settle_cycles": run.settle_cycles,
        "gamma_steps": [{"t_s": t, "gamma": g} for t, g in run.gamma_steps],
    }  # fmt: skip
    chans = {"continuity": x, "drive": rec.channels["drive"]}
    new = write_npz_run(tmp_path / f"dirty_{dropouts}", chans, fs=rec.fs, **spec)
    with caplog.at_level("WARNING"):
        flights, _ = extract_run(new)
    n_pressed = int(extract_pressed(flights).sum())
    print(f"{dropouts} openings: {n_pressed} pressed takeoffs")
    assert (n_pressed > 0) == bool(dropouts) and n_pressed <= dropouts
    assert ("pushed the body up" in caplog.text) == bool(dropouts)
    if dropouts:  # the other readings of many such takeoffs: levels, or drive phases off
        assert "contact_level" in caplog.text and "drive_phase_offset_rad" in caplog.text


def test_a_side_of_a_gain_step_without_rests_keeps_the_rc(make_rig, tmp_path):
    """The rig's bouncing body (e 0.5) with the channel's gain cut to 0.4 at 55 % of the
    recording: the side after the cut is bouncing alone (Gamma 2.8-4.2), with too few
    rests for a clean edge, so its RC constant was not measurable and its edges were
    placed by the box model: flight-time error median 9 us there against 0.8 us on the
    same flights unchanged. A gain step leaves the front end as it was: the side takes
    the whole's RC, and the error is the unchanged recording's within 0.5 us
    (reference: the rig's truth)."""
    from flights_synth import write_npz_run

    from bouncelab.runs import load_run, read_recording

    run_dir, truth_path = make_rig("gain_step_e0.5", rig_sweep(0.5, 0.002, seed=3))
    run, rec = load_run(run_dir), read_recording(run_dir)
    x = rec.channels["continuity"].copy()
    k = int(0.55 * x.shape[0])
    x[k:] *= 0.4
    spec = {
        "kind": "sweep", "drive_frequency_hz": run.drive_frequency_hz,
        "gamma_steps": [{"t_s": t, "gamma": g} for t, g in run.gamma_steps],
    }  # fmt: skip
    chans = {"continuity": x, "drive": rec.channels["drive"]}
    stepped = write_npz_run(tmp_path / "gain_step", chans, fs=rec.fs, **spec)
    truth, params = read_truth(truth_path)
    after = truth[truth["t_takeoff_s"] > k / rec.fs + 0.01]
    acc = {}
    for name, folder in (("clean", run_dir), ("stepped", stepped)):
        flights, _ = extract_run(folder)
        acc[name] = accuracy(flights, after, params["derived"]["duration_s"])
    print(acc)
    assert acc["stepped"]["found_long"] == 1.0
    assert acc["stepped"]["median_us"] < acc["clean"]["median_us"] + 0.5
