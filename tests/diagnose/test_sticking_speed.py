"""A body that sticks once its rebounds get slow (a real body's slow impacts; most
simulators' sticking thresholds) ends its chatter at a speed, which a constant
restitution does not: the diagnosis reads that speed from the data's chatter
(``gap.fit.sticking_speed``) and stops every simulation's slower rebounds there (the
kernel's ``stick_speed``). References: the model's own impact speeds (exact), and
pseudo-data made with a known sticking speed."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from bouncelab.gap.fit import STICK_SHARE, rebound_speeds, resolution_T, sticking_speed
from bouncelab.physics import Model
from bouncelab.physics.simulate import simulate_protocol

BOUNCY = Model.parse("restitution", {"e": 0.5})


def test_rebound_speeds_are_those_of_the_models_impacts():
    """A chatter rebound leaves at ``-e`` times the impact speed before it (the kernel's
    ``v_impact``); read back from its flight time and takeoff phase to 1e-5."""
    sim = simulate_protocol(BOUNCY, [1.3], [20])
    chatter = sim["chatter"].to_numpy()[1:]
    left = -0.5 * sim["v_impact"].to_numpy()[:-1]
    read = rebound_speeds(sim["T"].to_numpy()[1:], sim["phi_takeoff"].to_numpy()[1:], 1.3)
    assert chatter.sum() > 50
    np.testing.assert_allclose(read[chatter], left[chatter], rtol=1e-5)


def test_no_rebound_leaves_slower_than_the_sticking_speed():
    stick = 0.01  # g / omega
    sim = simulate_protocol(BOUNCY, [1.3, 1.8], [60, 60], stick_speed=stick)
    rebound = sim["chatter"].to_numpy()[1:]
    left = -0.5 * sim["v_impact"].to_numpy()[:-1]
    assert rebound.sum() > 100 and left[rebound].min() >= stick
    free = simulate_protocol(BOUNCY, [1.3, 1.8], [60, 60])
    assert (-0.5 * free["v_impact"].to_numpy()[:-1])[free["chatter"].to_numpy()[1:]].min() < stick
    # 0 is no sticking speed: bit-identical to the default
    zero = simulate_protocol(BOUNCY, [1.3, 1.8], [60, 60], stick_speed=0.0)
    np.testing.assert_array_equal(zero["T"].to_numpy(), free["T"].to_numpy())


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """A sweep run at 20 kHz, 30 Hz, 40 cycles per step over Gamma 0.8-3.2."""
    from bouncelab.runs import load_run

    d = tmp_path_factory.mktemp("stick") / "run"
    d.mkdir()
    gammas = np.round(np.linspace(0.8, 3.2, 13), 6)
    step_s = 40 / 30.0
    np.savez(d / "rec.npz", cont_v=np.zeros(10), drive_v=np.zeros(10))
    steps = [{"t_s": round(i * step_s, 9), "gamma": float(g)} for i, g in enumerate(gammas)]
    spec = {
        "format_version": 1, "kind": "sweep", "recording": "rec.npz",
        "sample_rate_hz": 20_000.0, "channels": {"continuity": "cont_v", "drive": "drive_v"},
        "drive_frequency_hz": 30.0, "settle_cycles": 10, "source": "synthetic",
        "gamma_steps": steps,
    }  # fmt: skip
    (d / "run.yaml").write_text(yaml.safe_dump(spec, sort_keys=False))
    return load_run(d), len(gammas) * step_s


@pytest.mark.parametrize("stick_mm_s", [0.0, 2.0, 10.0])
def test_the_sticking_speed_is_read_from_the_chatter(run, stick_mm_s):
    """Pseudo-data of e 0.5 whose rebounds stick below ``stick_mm_s``: read to within
    -5 % (the share kept below the slowest rebounds) and +15 % (the slowest rebounds lie
    up to 1/e above the speed, their 1 % quantile near it); none without one."""
    from bouncelab.protocol import simulate_run

    r, duration = run
    unit = 9.80665 / (2 * np.pi * 30.0)  # m/s per g / omega
    stick = stick_mm_s * 1e-3 / unit
    table = simulate_run(r, BOUNCY, duration, seed=1, stick_speed=stick)
    min_T = resolution_T(r)
    table = table[table["T"] >= min_T]
    read = sticking_speed(r, table, min_T, 0.0)
    print(f"{stick_mm_s} mm/s: read {read * unit * 1e3:.3f} mm/s")
    if stick_mm_s == 0.0:
        assert read == 0.0
    else:
        assert STICK_SHARE * stick <= read <= 1.15 * stick


def test_a_run_whose_body_sticks_has_its_simulations_stick_and_says_so(run):
    """``make_problem`` reads the speed from the data and every simulation of the fits
    then sticks below it; the diagnosis warns in one line, with the speed in mm/s."""
    from bouncelab.gap.diagnose import sticking_speed_warning
    from bouncelab.gap.fit import make_problem, simulate
    from bouncelab.protocol import simulate_run

    r, duration = run
    unit = 9.80665 / (2 * np.pi * 30.0)
    stick = 5e-3 / unit
    data = simulate_run(r, BOUNCY, duration, seed=1, stick_speed=stick)
    problem = make_problem(r, data, duration)
    assert STICK_SHARE * stick <= problem.stick_speed <= 1.15 * stick
    sim = simulate(problem, BOUNCY)
    rebound = sim["chatter"].to_numpy()[1:]
    assert rebound.sum() > 100
    assert (-0.5 * sim["v_impact"].to_numpy()[:-1])[rebound].min() >= problem.stick_speed
    line = sticking_speed_warning(problem)
    assert line.startswith("the body bounces, but no rebound leaves the plate slower than")
    assert f"{problem.stick_speed * unit * 1e3:.3g} mm/s stick" in line
    free = make_problem(r, simulate_run(r, BOUNCY, duration, seed=1), duration)
    assert free.stick_speed == 0.0 and sticking_speed_warning(free) is None
