"""Energy bookkeeping per flight: Delta(KE + PE) = plate work - friction loss - impact loss."""

import numpy as np
import pytest

from bouncelab.physics import Model, simulate_drop, simulate_grid, simulate_protocol

MODELS = [
    ("ideal", {}),
    ("friction", {"mu": 0.29}),
    ("restitution", {"e": 0.515}),
    ("harmonic", {"k": 2.5, "a": 0.15, "psi": 0.7}),
    ("feedback", {"mass_ratio": 0.2, "f_ratio": 0.45, "zeta": 0.1}),
    ("gamma_scale", {"s": 0.9}),
    ("friction+restitution", {"mu": 0.29, "e": 0.515}),
    ("friction+harmonic", {"mu": 0.2, "k": 0.4, "a": 0.2}),
    ("friction+restitution+harmonic+feedback+gamma_scale", {"mu": 0.2, "e": 0.4, "zeta": 0.3}),
    # a riding body loads the armature: the ride splits at the plate's turning points
    ("feedback", {"mass_ratio": 0.2, "f_ratio": 0.45, "zeta": 0.1, "ride_load": 1.0}),
    ("friction+feedback", {"mu": 0.29, "mass_ratio": 0.1, "f_ratio": 0.67, "ride_load": 1.0}),
    (
        "friction+restitution+harmonic+feedback",
        {"mu": 0.2, "e": 0.4, "k": 2.0, "a": 0.1, "zeta": 0.3, "ride_load": 1.0},
    ),
]


def residuals(df):
    """Per flight: change of (v^2/2 + x) from this takeoff to the next minus the budget.

    The mechanical energy comes from the body states at consecutive takeoffs
    (x_takeoff, v_takeoff); the budget terms are computed separately by the kernel
    (impact impulse times plate velocity, friction times path length, ...).
    """
    out = []
    for _, g in df.groupby(["gamma", "start"], sort=False):
        g = g.sort_values("flight")
        consecutive = np.diff(g["flight"].to_numpy()) == 1
        e_mech = 0.5 * g["v_takeoff"].to_numpy() ** 2 + g["x_takeoff"].to_numpy()
        budget = (g["e_plate"] - g["e_friction"] - g["e_impact"]).to_numpy()[:-1]
        out.append((np.diff(e_mech) - budget)[consecutive])
    return np.concatenate(out)


@pytest.mark.parametrize(("name", "params"), MODELS)
def test_energy_closes_every_flight(name, params):
    # tolerance 1e-9 (per unit mass, (g/omega)^2) on every flight
    df = simulate_grid(
        Model.parse(name, params), np.linspace(1.05, 7.5, 14), 300, n_skip=20, n_starts=2
    )
    res = residuals(df)
    assert res.size > 3000
    assert np.max(np.abs(res)) < 1e-9
    # losses are losses
    assert (df["e_friction"] >= 0).all() and (df["e_impact"] >= -1e-15).all()


def test_energy_closes_across_protocol_steps():
    # Gamma changes under a riding or flying body; the plate's jump is plate work
    m = Model.parse("friction+restitution+harmonic", {"mu": 0.2, "e": 0.3})
    df = simulate_protocol(m, [1.5, 2.5, 3.3, 4.0, 2.0], [30, 40, 30, 50, 20], n_starts=2)
    assert np.max(np.abs(residuals(df))) < 1e-9


def test_impact_loss_formula():
    # reference: (1 - e^2) v_rel^2 / 2 in the plate frame (infinitely heavy plate) for
    # every impact that rebounds; tolerance 1e-12
    e = 0.6
    df = simulate_grid(Model.parse("restitution", {"e": e}), [2.2, 3.1], 200)
    keep = df["tail"] == 0
    loss = (1 - e * e) * df["v_impact"] ** 2 / 2
    assert np.allclose(df["e_impact"][keep], loss[keep], rtol=0, atol=1e-12)


def test_drop_energy():
    # still plate: the whole drop height ends as friction + impact loss (plate work 0
    # on a still, infinitely heavy plate); tolerance 1e-9
    h, mu, e = 1.3, 0.29, 0.515
    df = simulate_drop(Model.parse("friction+restitution", {"mu": mu, "e": e}), h)
    assert abs(df["e_plate"]).max() < 1e-15
    assert df["e_friction"].sum() + df["e_impact"].sum() == pytest.approx(h, abs=1e-9)


def test_energy_closes_through_long_loaded_rides_with_friction():
    """A loaded armature with friction, Gamma steps where the body cannot leave for many
    cycles (0.6 < 1 - mu) between steps where it flies: the friction path is the loaded
    plate's, so the balance closes across the whole protocol (not only within a Gamma)."""
    params = {"mu": 0.29, "mass_ratio": 0.1, "f_ratio": 0.67, "ride_load": 1.0}
    m = Model.parse("friction+feedback", params)
    # 150 cycles at 0.6: longer than the 64-cycle search for a takeoff (RIDE_CYCLES)
    df = simulate_protocol(m, [2.0, 0.6, 2.5, 0.6, 3.0], [30, 150, 30, 150, 30], settle_cycles=0)
    df = df.sort_values("flight")
    assert (df["step"] == 2).sum() > 10 and (df["step"] == 4).sum() > 10
    assert (df["step"] == 1).sum() == 0  # no flight at 0.6
    consecutive = np.diff(df["flight"].to_numpy()) == 1
    e_mech = 0.5 * df["v_takeoff"].to_numpy() ** 2 + df["x_takeoff"].to_numpy()
    budget = (df["e_plate"] - df["e_friction"] - df["e_impact"]).to_numpy()[:-1]
    res = (np.diff(e_mech) - budget)[consecutive]
    assert consecutive.sum() > 40
    assert np.max(np.abs(res)) < 1e-9


def test_long_loaded_ride_reaches_the_same_steady_state():
    """Riding 150 cycles at Gamma 0.6 (longer than the 64-cycle takeoff search) must leave
    the loaded armature in the same steady state as riding 60 cycles: its free part has
    decayed (by e^-23) in both, so the next step's flights agree to 1e-7 rad.  (With the
    friction load's sign tracked at turning points, the jump to the step's end carried a
    wrong static deflection: 0.03 rad.)"""
    params = {"mu": 0.29, "mass_ratio": 0.1, "f_ratio": 0.67, "ride_load": 1.0}
    m = Model.parse("friction+feedback", params)
    out = []
    for n in (60, 150):
        df = simulate_protocol(m, [0.6, 2.5], [n, 20], settle_cycles=0)
        out.append(df["T"].to_numpy()[:8])
    assert out[0].size == 8
    assert np.max(np.abs(out[0] - out[1])) < 1e-7
