"""The takeoff reading (bouncelab.gap.takeoff_reading): the takeoff condition against its
analytic phases, the steps it keeps, and the harmonic and friction it reads off
recordings of the independent generator (benchmarks/independent_rig.py), scored against
that generator's truth."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from bouncelab.flights import extract_run
from bouncelab.gap.takeoff_reading import predicted_takeoff, read_takeoffs, ride_takeoffs

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
from independent_rig import make_case  # noqa: E402


@pytest.mark.parametrize(("gamma", "mu"), [(2.0, 0.0), (2.0, 0.2), (1.5, 0.3)])
def test_a_sine_plate_is_left_where_the_takeoff_window_opens(gamma, mu):
    # reference: the kernels' takeoff window on a sine plate, lo = arcsin((1 + mu) / Gamma)
    # (physics.kernels.takeoff_window); a ride from pi waits for the next cycle's lo.
    # Tolerance 1e-3 rad: the crossing is interpolated on a 1-degree grid
    got = predicted_takeoff(np.array([gamma]), np.array([math.pi]), 2.0, 0.0, 0.0, mu)[0]
    assert got == pytest.approx(2 * math.pi + math.asin((1 + mu) / gamma), abs=1e-3)


def test_a_plate_that_never_exceeds_gravity_is_never_left():
    got = predicted_takeoff(np.array([0.9]), np.array([0.0]), 2.0, 0.0, 0.0, 0.0)
    assert np.isnan(got[0])


def _table(phases_by_step, ride_s=0.02, flight_s=0.01, hz=30.0):
    """A flight table whose every takeoff follows a ride of ``ride_s``."""
    rows, t = [], 0.0
    for step, (gamma, phases) in enumerate(phases_by_step):
        for phi in phases:
            t += ride_s
            rows.append(
                {"step": step, "gamma": gamma, "t_takeoff_s": t, "t_landing_s": t + flight_s,
                 "phi_takeoff": phi % (2 * math.pi)}
            )  # fmt: skip
            t += flight_s
    return pd.DataFrame(rows)


def test_a_step_that_leaves_from_two_places_is_not_read():
    # one step's takeoffs gather at 0.5 rad; the other's split between 0.3 and 1.7 rad
    # (a step between two regimes): only the first is kept, with its ride's start
    one = [0.5 + 0.001 * i for i in range(8)]
    two = [0.3, 1.7] * 4
    points = ride_takeoffs(_table([(1.5, one), (1.6, two)]), 30.0)
    assert list(points["step"]) == [0]
    assert points["phi_takeoff"].iloc[0] == pytest.approx(0.5035, abs=1e-3)
    # the ride of 0.02 s at 30 Hz began 0.6 cycle (3.77 rad) before the takeoff
    start = (0.5035 - 2 * math.pi * 0.6) % (2 * math.pi)
    assert points["phi_start"].iloc[0] == pytest.approx(start, abs=1e-3)
    assert points["n"].iloc[0] == 7  # the first takeoff has no landing before it


def test_a_run_without_phases_has_nothing_to_read():
    # a run without a drive channel has NaN phases (CONTRACTS.md section 3)
    table = _table([(1.5, [0.5] * 8), (1.6, [0.6] * 8)])
    points = ride_takeoffs(table.assign(phi_takeoff=np.nan), 30.0)
    assert points.empty
    assert read_takeoffs(points) == {"n_steps": 0}


def _read(tmp_path, **case):
    run_dir = tmp_path / "case"
    make_case(run_dir, **case)
    flights, _qc = extract_run(run_dir)
    truth = json.loads(run_dir.with_name("case.truth.json").read_text())
    return read_takeoffs(ride_takeoffs(flights, case.get("f", 30.0))), truth["effects"]


def test_a_harmonic_and_friction_are_read_off_an_independent_recording(tmp_path):
    # reference: the generator's truth (k 3, a 0.05, psi 1.0, mu 0.2). Tolerances a within
    # 5 %, psi 0.05 rad, mu 0.01: on the benchmark's five integer-k harmonics without a
    # Gamma miscalibration or k 5 the reading is within 2 %, 0.03 rad and 0.002
    # (benchmarks/results/takeoff_reading.json)
    reading, truth = _read(
        tmp_path, g0=0.8, g1=2.6, dg=0.1, step_s=1.0, mu=0.2, k=3.0, a=0.05, psi=1.0, seed=5
    )
    best = reading["best"]
    assert best["k"] == 3.0
    assert best["a"] == pytest.approx(truth["harmonic"]["a"], rel=0.05)
    assert best["psi"] == pytest.approx(truth["harmonic"]["psi"], abs=0.05)
    assert best["mu"] == pytest.approx(truth["friction"]["mu"], abs=0.01)
    assert reading["plain"]["rms_rad"] > 10 * best["rms_rad"]  # no harmonic fits far worse


def test_friction_alone_reads_as_friction_with_no_harmonic_to_speak_of(tmp_path):
    # reference: the generator's truth (mu 0.15, no harmonic): the plain fit's mu within
    # 0.01, and no harmonic takes more than 2 % of the plate's acceleration (a k^2)
    reading, truth = _read(tmp_path, g0=0.8, g1=2.6, dg=0.1, step_s=1.0, mu=0.15, seed=6)
    assert reading["plain"]["mu"] == pytest.approx(truth["friction"]["mu"], abs=0.01)
    assert all(r["a"] * r["k"] ** 2 < 0.02 for r in reading["by_k"])


def _exact_points(n_steps, mu):
    """Takeoffs of the condition itself on a sine plate, rides from pi, Gamma 1.2-2."""
    gammas = np.linspace(1.2, 2.0, n_steps)
    starts = np.full(n_steps, math.pi)
    phi = predicted_takeoff(gammas, starts, 2.0, 0.0, 0.0, mu) % (2 * math.pi)
    return pd.DataFrame({"gamma": gammas, "phi_start": starts, "phi_takeoff": phi})


def test_too_few_steps_are_not_read():
    from bouncelab.gap.takeoff_reading import MIN_STEPS

    assert read_takeoffs(_exact_points(MIN_STEPS - 1, 0.1)) == {"n_steps": MIN_STEPS - 1}
    # one step more, and mu is read back from its own takeoffs (reference: the 0.1 they
    # were made with; the crossing is interpolated, 1e-3)
    reading = read_takeoffs(_exact_points(MIN_STEPS, 0.1))
    assert reading["plain"]["mu"] == pytest.approx(0.1, abs=1e-3)
