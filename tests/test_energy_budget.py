"""Energy bookkeeping in SI and the reconstruction of the seed's two energy numbers."""

import math

import pandas as pd
import pytest

from bouncelab.energy import (
    energy_budget,
    energy_scale_j,
    flight_with_friction,
    seed_energy_reconstruction,
)


def test_energy_scale_is_m_g_over_omega_squared():
    # reference: m (g/omega)^2 by hand for 249 g at 30 Hz
    omega = 2 * math.pi * 30.0
    assert energy_scale_j(0.249, 30.0, g=9.81) == pytest.approx(0.249 * (9.81 / omega) ** 2)


@pytest.mark.parametrize("mu", [0.0, 0.1, 0.29, 0.5])
def test_friction_flight_closes_the_work_energy_balance(mu):
    # reference: kinetic energy at takeoff - at landing = mu m g x path (same height)
    m, g, T = 0.249, 9.81, 0.11
    f = flight_with_friction(T, mu, g)
    lost = 0.5 * m * (f["v_takeoff"] ** 2 - f["v_landing"] ** 2)
    assert lost == pytest.approx(mu * m * g * f["path_m"], rel=1e-12, abs=1e-15)
    if mu == 0.0:  # symmetric parabola: v = g T / 2, apex g T^2 / 8
        assert f["v_takeoff"] == pytest.approx(g * T / 2)
        assert f["apex_m"] == pytest.approx(g * T * T / 8)


def test_seed_friction_number_is_a_landing_energy_difference():
    # the seed's 0.0122 J is reproduced to 1 % by one reading and not by the friction work
    rows = seed_energy_reconstruction()
    landing, work = rows[0], rows[1]
    assert landing["value_j"] == pytest.approx(0.0122, rel=0.01)
    assert work["value_j"] > 1.5 * 0.0122


def test_seed_restitution_number_within_five_percent():
    # the seed's 0.00498 J against a rebound after a fall of T/2 at g(1 - mu): 3 % off
    assert seed_energy_reconstruction()[2]["value_j"] == pytest.approx(0.00498, rel=0.05)


def test_budget_counts_settled_flights_per_cycle():
    # two settled flights of one period each, one unsettled: 2 cycles, sums / 2
    flights = pd.DataFrame(
        {
            "step": [0, 0, 0],
            "gamma": [3.0, 3.0, 3.0],
            "T": [2 * math.pi, 2 * math.pi, 2 * math.pi],
            "e_friction": [1.0, 3.0, 100.0],
            "e_impact": [2.0, 2.0, 100.0],
            "e_plate": [3.0, 5.0, 100.0],
            "settled": [True, True, False],
        }
    )
    b = energy_budget(flights, mass_kg=1.0, drive_frequency_hz=1.0, g=2 * math.pi)
    # with g = omega the energy scale is m (g/omega)^2 = 1 J
    assert b["cycles"].iloc[0] == pytest.approx(2.0)
    assert b["friction_j"].iloc[0] == pytest.approx(2.0)
    assert b["impact_j"].iloc[0] == pytest.approx(2.0)
    assert b["plate_j"].iloc[0] == pytest.approx(4.0)
    assert b["friction_share"].iloc[0] == pytest.approx(0.5)
