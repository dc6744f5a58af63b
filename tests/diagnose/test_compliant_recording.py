"""Recordings from the third generator (``benchmarks/compliant_rig.py``: no impact map, a
Kelvin-Voigt contact whose damping makes the restitution, one ODE integrated by RK4)
checked against analytic values, then diagnosed. References: the period-1 orbit of a
bouncing ball and the generator's truth, read only after the diagnosis."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import pytest

from bouncelab.flights import extract_run
from bouncelab.gap.diagnose import diagnose_run

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
from compliant_rig import bounce_once, contact_for, make_case  # noqa: E402


@pytest.mark.parametrize("e", [0.3, 0.5, 0.8])
def test_the_contact_returns_the_restitution_it_was_made_for(e):
    """``contact_for`` finds the damping that gives ``e`` (bisection); the Kelvin-Voigt
    contact's restitution does not depend on the impact speed (a linear system), and it
    lasts about the half period asked for (less with damping: the force reaches zero
    before the spring is relaxed). Reference: e itself, to 1e-6 at 0.3 m/s, 1e-3 at
    0.05 and 1 m/s (the integration's steps); the contact time within 25 % of 100 us."""
    k_c, c_c = contact_for(e, 1e-4, 2e-6)
    assert bounce_once(0.3, k_c, c_c, False, 1e-7)[0] == pytest.approx(e, abs=1e-6)
    for v0 in (0.05, 1.0):
        e_v, t_contact = bounce_once(v0, k_c, c_c, False, 1e-7)
        assert e_v == pytest.approx(e, abs=1e-3)
        assert 0.75e-4 < t_contact <= 1.0e-4


def test_the_hertzian_contact_loses_less_at_low_speed():
    """The out-of-library contact: a Hunt-Crossley law, whose restitution falls with the
    impact speed (``1 - e`` about proportional to it). Reference: e 0.4 at 0.3 m/s (the
    speed it is made for), higher below, lower above."""
    k_c, c_c = contact_for(0.4, 1e-4, 2e-6, hertz=True)
    e_at = [bounce_once(v, k_c, c_c, True, 1e-7)[0] for v in (0.05, 0.3, 1.0)]
    assert e_at[1] == pytest.approx(0.4, abs=1e-6)
    assert e_at[0] > 0.7 and e_at[2] < 0.2


@pytest.mark.parametrize(
    ("gamma", "e", "periods"),
    [(2.0, 0.0, 0.74148), (1.3, 0.5, 2.876205 / (2.0 * math.pi))],
)
def test_a_flight_from_rest_is_the_ideal_balls(tmp_path, gamma, e, periods):
    """The generator has no impact map and no takeoff rule: a body resting on the
    compressed contact leaves when the plate falls faster than gravity, as the ideal ball
    does from rest (DESIGN.md section 1). Below the first locking every cycle has such a
    flight: at Gamma 2 on the plastic contact (e 0.004), each flight; at Gamma 1.3 with e
    0.5, the long flight after the chatter has died out. Reference: the ideal ball's
    flight from rest, 0.74148 drive periods at Gamma 2 (DESIGN.md) and the root of
    DESIGN.md's flight equation at Gamma 1.3 (2.876205 rad, brentq); for the mean of the
    last 40 such flights, within half a sample of the 20 kHz recording (0.0047 rad at
    30 Hz), the edges' resolution."""
    f_hz, fs = 30.0, 20000.0
    run_dir = tmp_path / "from_rest"
    make_case(run_dir, g0=gamma, g1=gamma, dg=1.0, step_s=4.0, e=e, noise_v=0.001, f=f_hz,
              fs=fs)  # fmt: skip
    flights, _qc = extract_run(run_dir)
    long = flights.loc[flights["settled"] & (flights["T"] > 1.0), "T"].to_numpy()[-40:]
    assert len(long) == 40
    assert long.mean() == pytest.approx(2.0 * math.pi * periods, abs=math.pi * f_hz / fs)


def test_restitution_through_a_compliant_contact_is_found_and_explained(tmp_path):
    """A compliant contact (100 us, e 0.45 made by its damping, not by a map), 28 Hz,
    Gamma 0.8-3.2: the diagnosis finds restitution alone, explained, e within 5 % and
    the contact time within 15 % (the pile-up of the contacts reads about 90 us: the
    damped contact is shorter than the spring's half period). The benchmark's longer
    cases (``bench_independent.py --generator compliant``) recover e within 1 %."""
    run_dir = tmp_path / "compliant"
    make_case(run_dir, f=28.0, g0=0.8, g1=3.2, dg=0.1, step_s=1.2, e=0.45, seed=21)
    diag = diagnose_run(run_dir, workers=1, progress=False)
    truth = json.loads(run_dir.with_name("compliant.truth.json").read_text())
    assert diag["selected"] == ["restitution"], diag["selected"]
    assert diag["steps"][0]["params"]["e"] == pytest.approx(truth["effects"]["restitution"]["e"],
                                                           rel=0.05)  # fmt: skip
    assert not diag["unexplained"], diag["unexplained_reasons"]
    contact = truth["contact_time_s"]["0.5_m_s"]
    assert diag["design"]["min_contact_s"] == pytest.approx(contact, rel=0.15)


def test_a_compliant_drop_test_calibrates_to_the_contacts_friction_and_restitution(tmp_path):
    """``bouncelab calibrate`` on a drop test with no impact map: the seed's rig (mu 0.29,
    e 0.515, 249 g in the seed, 0.2 kg here, 5 cm), each contact lasting 87 us.
    Reference: the generator's truth, mu within 2 % and e within 2 % (measured 0.03 % and
    0.7 %: friction and gravity act during the contact too, which takes a little more of
    the slow last bounces' speed; ``bench_compliant_drop.py``, 8 cases, all within 1.4 %)."""
    from compliant_rig import make_drop

    from bouncelab.calibration import calibrate_run

    truth = make_drop(tmp_path / "drop", mu=0.29, e=0.515, h=0.05)
    cal = calibrate_run(tmp_path / "drop", n_boot=200)
    assert cal["n_bounces"] >= 3
    assert cal["mu"] == pytest.approx(truth["mu"], rel=0.02)
    assert cal["restitution"] == pytest.approx(truth["e"], rel=0.02)
